// An inshade network as a three.js material (written by `inshade export-three` beside network.json and
// network.bin). For a WebGLRenderer:
//
//   import { loadNetworkMesh } from "./my_net/inshade-three.js";
//   scene.add(await loadNetworkMesh(new URL("./my_net/", import.meta.url)));
//
// An image is a 1 x 1 plane (or `loadNetworkMaterial(base)` on a mesh of your own: its uv is the
// network's input); an SDF is a box around its bound, drawn from the inside and sphere traced per
// fragment, in the mesh's frame; a radiance field is its box, drawn from the inside and marched per
// fragment, its radiance laid over what is behind it (premultiplied: ONE, ONE_MINUS_SRC_ALPHA).
// Texels are data: no colour space, no flip, no mipmaps generated.
import * as THREE from "three";

// inshade dtype -> three.js texel type, typed array and internal format by channel count
const TYPES = {
  f4: {type: THREE.FloatType, array: Float32Array, internal: {1: "R32F", 2: "RG32F", 4: "RGBA32F"}, alpha: 1.0},
  f2: {type: THREE.HalfFloatType, array: Uint16Array, internal: {1: "R16F", 2: "RG16F", 4: "RGBA16F"}, alpha: 0x3c00},
  f1: {type: THREE.UnsignedByteType, array: Uint8Array, internal: {1: "R8", 2: "RG8", 4: "RGBA8"}, alpha: 255},
  u4: {type: THREE.UnsignedIntType, array: Uint32Array, internal: {1: "R32UI", 2: "RG32UI", 4: "RGBA32UI"}, alpha: 1,
       integer: true},
};
const FORMATS = {1: THREE.RedFormat, 2: THREE.RGFormat, 4: THREE.RGBAFormat};
const INTEGER_FORMATS = {1: THREE.RedIntegerFormat, 2: THREE.RGIntegerFormat, 4: THREE.RGBAIntegerFormat};
const WRAPS = {repeat: THREE.RepeatWrapping, clamp: THREE.ClampToEdgeWrapping, mirror: THREE.MirroredRepeatWrapping};

// one level's texels as the format holds them: RGB gains an alpha (WebGL2 renders nothing into RGB
// float textures and three.js has no RGB format); 16-bit normalised cells become floats q / 65535
function texels(rec, data, [offset, nbytes]) {
  if (rec.dtype === "nu2") {
    const q = new Uint16Array(data, offset, nbytes / 2);
    return texels({...rec, dtype: "f4"}, Float32Array.from(q, (v) => v / 65535).buffer, [0, q.length * 4]);
  }
  const spec = TYPES[rec.dtype];
  const values = new spec.array(data, offset, nbytes / spec.array.BYTES_PER_ELEMENT);
  if (rec.channels !== 3) return {values, dtype: rec.dtype};
  const n = values.length / 3, out = new spec.array(n * 4);
  for (let i = 0; i < n; ++i) {
    out.set(values.subarray(i * 3, i * 3 + 3), i * 4);
    out[i * 4 + 3] = spec.alpha;
  }
  return {values: out, dtype: rec.dtype};
}

function texture(rec, data) {
  const levels = rec.levels.map((level) => texels(rec, data, level));
  const spec = TYPES[levels[0].dtype], channels = rec.channels === 3 ? 4 : rec.channels;
  const format = (spec.integer ? INTEGER_FORMATS : FORMATS)[channels];
  const [w, h, d] = rec.size;
  let tex;
  if (rec.kind === "2d") {
    tex = new THREE.DataTexture(levels[0].values, w, h, format, spec.type);
    if (levels.length > 1) {
      tex.mipmaps = levels.map((l, k) => ({data: l.values, width: Math.max(w >> k, 1), height: Math.max(h >> k, 1)}));
    }
  } else {
    if (levels.length > 1) throw new Error(`texture ${rec.uniform}: mip levels of a ${rec.kind} texture are not drawn here`);
    tex = rec.kind === "3d" ? new THREE.Data3DTexture(levels[0].values, w, h, d)
      : new THREE.DataArrayTexture(levels[0].values, w, h, d);
    tex.format = format;
    tex.type = spec.type;
  }
  tex.internalFormat = spec.internal[channels];
  const linear = rec.filter === "linear";
  tex.magFilter = linear ? THREE.LinearFilter : THREE.NearestFilter;
  tex.minFilter = levels.length > 1 ? (linear ? THREE.LinearMipmapNearestFilter : THREE.NearestMipmapNearestFilter)
    : (linear ? THREE.LinearFilter : THREE.NearestFilter);
  tex.wrapS = tex.wrapT = WRAPS[rec.wrap] ?? THREE.ClampToEdgeWrapping;
  if (rec.kind === "3d") tex.wrapR = THREE.ClampToEdgeWrapping;
  tex.generateMipmaps = false;
  tex.flipY = false;
  tex.unpackAlignment = 1;
  tex.colorSpace = THREE.NoColorSpace;
  tex.needsUpdate = true;
  return tex;
}

async function fetched(url, how) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: ${response.status} ${response.statusText}`);
  return how === "json" ? response.json() : response.arrayBuffer();
}

// The network's ShaderMaterial: base is the folder's URL (ending in /).
export async function loadNetworkMaterial(base) {
  const manifest = await fetched(new URL("network.json", base), "json");
  if (manifest.format !== "inshade-three 1") throw new Error(`network.json: format: unknown ${manifest.format}`);
  const data = await fetched(new URL("network.bin", base), "bytes");
  const uniforms = Object.fromEntries(manifest.textures.map((rec) => [rec.uniform, {value: texture(rec, data)}]));
  for (const [name, value] of Object.entries(manifest.uniforms)) {   // vec3 arrays (an SDF's SH environment)
    uniforms[name] = {value: value.map((v) => new THREE.Vector3(...v))};
  }
  const material = new THREE.ShaderMaterial({glslVersion: THREE.GLSL3, vertexShader: manifest.vertexShader,
                                             fragmentShader: manifest.fragmentShader, uniforms,
                                             transparent: manifest.alpha, side: SIDES[manifest.kind]});
  if (manifest.kind === "field") Object.assign(material, PREMULTIPLIED);
  material.name = manifest.name;
  material.userData.inshade = {kind: manifest.kind, bound: manifest.bound, box: manifest.box};
  return material;
}

// a box is drawn from the inside, so every ray through it reaches its fragments
const SIDES = {image: THREE.FrontSide, sdf: THREE.BackSide, field: THREE.BackSide};
// a field's fragment is its radiance and coverage, premultiplied; a volume writes no depth
const PREMULTIPLIED = {blending: THREE.CustomBlending, blendSrc: THREE.OneFactor,
                              blendDst: THREE.OneMinusSrcAlphaFactor, blendSrcAlpha: THREE.OneFactor,
                              blendDstAlpha: THREE.OneMinusSrcAlphaFactor, depthWrite: false};

// The mesh a kind is drawn on, in the network's own frame.
function networkGeometry(kind, {bound, box} = {}) {
  if (kind === "sdf") {
    const side = 2 * bound.radius;
    return new THREE.BoxGeometry(side, side, side).translate(...bound.center);
  }
  if (kind === "field") {
    const [lo, hi] = box;
    return new THREE.BoxGeometry(...hi.map((h, i) => h - lo[i])).translate(...hi.map((h, i) => (h + lo[i]) / 2));
  }
  return new THREE.PlaneGeometry(1, 1);
}

// The network as a mesh: an image on a 1 x 1 plane in the xy plane (uv (0, 0) bottom left) facing +z;
// an SDF in the box around its bound sphere, a field in its box, in the network's own frame.
export async function loadNetworkMesh(base) {
  const material = await loadNetworkMaterial(base);
  const {kind, ...where} = material.userData.inshade;
  const mesh = new THREE.Mesh(networkGeometry(kind, where), material);
  mesh.name = material.name;
  return mesh;
}
