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
import { loadNetworkData } from "./inshade-three-data.js";

// The network's ShaderMaterial: base is the folder's URL (ending in /).
export async function loadNetworkMaterial(base) {
  const {manifest, textures} = await loadNetworkData(base, true);
  const uniforms = Object.fromEntries(textures(manifest.textures).map(([name, value]) => [name, {value}]));
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
