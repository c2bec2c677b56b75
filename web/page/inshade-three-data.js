// The data of an inshade three.js material (network.json and network.bin, written by `inshade export-three`)
// as three.js objects, for inshade-three.js (WebGLRenderer) and inshade-three-webgpu.js (WebGPURenderer).
// Texels are data: no colour space, no flip, no mipmaps generated.
import * as THREE from "three";

// inshade dtype -> three.js texel type, typed array and internal format by channel count
const TYPES = {
  f4: {type: THREE.FloatType, array: Float32Array, internal: {1: "R32F", 2: "RG32F", 4: "RGBA32F"}, alpha: 1.0},
  f2: {type: THREE.HalfFloatType, array: Uint16Array, internal: {1: "R16F", 2: "RG16F", 4: "RGBA16F"}, alpha: 0x3c00},
  f1: {type: THREE.UnsignedByteType, array: Uint8Array, internal: {1: "R8", 2: "RG8", 4: "RGBA8"}, alpha: 255},
  u4: {type: THREE.UnsignedIntType, array: Uint32Array, internal: {1: "R32UI", 2: "RG32UI", 4: "RGBA32UI"}, alpha: 1,
       integer: true},
  u1: {type: THREE.UnsignedByteType, array: Uint8Array, internal: {1: "R8UI", 2: "RG8UI", 4: "RGBA8UI"}, alpha: 1,
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

function texture(rec, data, webgl) {
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
  // WebGL's sized format; a WebGPURenderer derives its own from format and type (it reads this field as a
  // WebGPU format name)
  if (webgl) tex.internalFormat = spec.internal[channels];
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

// {manifest, textures(records) -> [[uniform, THREE texture], ...]}: base is the folder's URL (ending in /);
// webgl: the textures are for a WebGLRenderer (else a WebGPURenderer)
export async function loadNetworkData(base, webgl) {
  const manifest = await fetched(new URL("network.json", base), "json");
  if (manifest.format !== "inshade-three 1") throw new Error(`network.json: format: unknown ${manifest.format}`);
  const data = await fetched(new URL("network.bin", base), "bytes");
  return {manifest, textures: (records) => records.map((rec) => [rec.uniform, texture(rec, data, webgl)])};
}

// Every mesh of GLTFLoader's result gltf drawn with the file's material `index` (its parser says which is
// which) gets make(fileMaterial, tangents) instead (one per file material; tangents: the mesh has a
// tangent attribute). Returns the meshes changed; none is an error.
export function replaceMaterial(gltf, index, name, make) {
  const made = new Map(), meshes = [];
  gltf.scene.traverse((o) => {
    if (!o.isMesh || gltf.parser.associations.get(o.material)?.materials !== index) return;
    if (!made.has(o.material)) made.set(o.material, make(o.material, "tangent" in o.geometry.attributes));
    o.material = made.get(o.material);
    meshes.push(o);
  });
  if (!meshes.length) throw new Error(`${name}: no mesh of this glTF scene is drawn with material ${index}`);
  return meshes;
}
