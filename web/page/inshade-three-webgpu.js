// An inshade network as a three.js node material for a WebGPURenderer (written by `inshade export-three`
// beside network.json). The network's WGSL, the same code `inshade codegen --target wgsl` writes and
// checks, is the material's colour through TSL's wgslFn:
//
//   import { loadNetworkNodeMesh } from "./my_net/inshade-three-webgpu.js";
//   scene.add(await loadNetworkNodeMesh(new URL("./my_net/", import.meta.url)));
//
// An image is a 1 x 1 plane (its uv the network's input); an SDF is a box around its bound, drawn from
// the inside and sphere traced per fragment; a radiance field is its box, drawn from the inside and
// marched per fragment, its radiance laid over what is behind it (premultiplied); both in the mesh's
// frame; network SDFs only (network.json says why another is not taken). The network's lookup arrays
// and grids are three textures, which its WGSL takes as arguments. Its data comes through
// inshade-three-data.js, which imports "three": map it as three's WebGPU examples do (to three.webgpu.js).
import { BackSide, BoxGeometry, CustomBlending, Mesh, MeshBasicNodeMaterial, OneFactor, OneMinusSrcAlphaFactor,
  PlaneGeometry } from "three/webgpu";
import { cameraPosition, modelWorldMatrixInverse, positionLocal, texture, texture3D, uv, vec4, wgsl, wgslFn }
  from "three/tsl";
import { loadNetworkData } from "./inshade-three-data.js";

// the camera's position and the fragment's, in the mesh's frame: a box's view ray
const ray = () => ({ro: modelWorldMatrixInverse.mul(vec4(cameraPosition, 1.0)).xyz, p: positionLocal});
// kind -> the node material's colour from the network's function, and the material's settings
const KINDS = {
  image: {inputs: () => ({uv: uv()}), settings: (manifest) => ({transparent: manifest.alpha})},
  sdf: {inputs: ray, settings: () => ({side: BackSide, alphaTest: 0.5})},   // a miss: alpha 0
  field: {
    inputs: ray,
    settings: () => ({transparent: true, side: BackSide, depthWrite: false, blending: CustomBlending,
                      blendSrc: OneFactor, blendDst: OneMinusSrcAlphaFactor, blendSrcAlpha: OneFactor,
                      blendDstAlpha: OneMinusSrcAlphaFactor}),
  },
};

// each texture parameter of the network's function -> its texture node (a sampler parameter: the same
// node, which three passes as the texture's sampler)
function textureArguments(wgslRecord, textures) {
  const nodes = Object.fromEntries(textures(wgslRecord.textures).map(([name, tex]) =>
    [name, tex.isData3DTexture ? texture3D(tex) : texture(tex)]));
  return Object.fromEntries(Object.entries(wgslRecord.arguments).map(([parameter, name]) => [parameter, nodes[name]]));
}

// The network's node material: base is the folder's URL (ending in /).
export async function loadNetworkNodeMaterial(base) {
  const {manifest, textures} = await loadNetworkData(base, false);
  if (!manifest.wgsl) throw new Error(`${manifest.name}: ${manifest.wgsl_unavailable}`);
  const kind = KINDS[manifest.kind];
  const material = new MeshBasicNodeMaterial(kind.settings(manifest));
  const fn = wgslFn(manifest.wgsl.function, [wgsl(manifest.wgsl.include)]);
  material.colorNode = fn({...kind.inputs(), ...textureArguments(manifest.wgsl, textures)});
  material.name = manifest.name;
  material.userData.inshade = {kind: manifest.kind, bound: manifest.bound, box: manifest.box};
  return material;
}

// The mesh a kind is drawn on, in the network's own frame (inshade-three.js's, on three/webgpu).
function networkGeometry(kind, {bound, box} = {}) {
  if (kind === "sdf") {
    const side = 2 * bound.radius;
    return new BoxGeometry(side, side, side).translate(...bound.center);
  }
  if (kind === "field") {
    const [lo, hi] = box;
    return new BoxGeometry(...hi.map((h, i) => h - lo[i])).translate(...hi.map((h, i) => (h + lo[i]) / 2));
  }
  return new PlaneGeometry(1, 1);
}

// The network as a mesh: an image on a 1 x 1 plane in the xy plane (uv (0, 0) bottom left) facing +z;
// an SDF in the box around its bound sphere, a field in its box, in the network's own frame.
export async function loadNetworkNodeMesh(base) {
  const material = await loadNetworkNodeMaterial(base);
  const {kind, ...where} = material.userData.inshade;
  const mesh = new Mesh(networkGeometry(kind, where), material);
  mesh.name = material.name;
  return mesh;
}
