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
import { BackSide, BoxGeometry, CustomBlending, MathUtils, Mesh, MeshBasicNodeMaterial, MeshPhysicalNodeMaterial,
  MeshStandardNodeMaterial, OneFactor, OneMinusSrcAlphaFactor, PlaneGeometry, Vector2 } from "three/webgpu";
import { cameraPosition, float, modelWorldMatrixInverse, normalMap, positionLocal, texture, texture3D, uniform, uv,
  vec4, wgsl, wgslFn } from "three/tsl";
import { loadNetworkData, replaceMaterial } from "./inshade-three-data.js";

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

// The file's material `file` as a node material with the network's channels (the function's columns:
// base colour and roughness, normal and occlusion, metallic) in place of its maps; its other parts stay
// the file's. tangents: the mesh has a tangent attribute (else three derives the frame and GLTFLoader
// flips y).
function decodedNodeMaterial(file, manifest, channels, tangents) {
  const m = new (file.isMeshPhysicalMaterial ? MeshPhysicalNodeMaterial : MeshStandardNodeMaterial)();
  for (const key in file) m[key] = file[key];   // as three's WebGPURenderer turns a material into nodes
  m.uuid = MathUtils.generateUUID();
  m.name = `${file.name} (${manifest.name})`;
  const scale = file.normalMap ? [Math.sign(file.normalScale.x) || 1, Math.sign(file.normalScale.y) || 1]
    : [1, tangents ? 1 : -1];   // the decoded normal is at full strength already
  const alpha = file.map && (file.transparent || file.alphaTest > 0) ? texture(file.map).a : float(1.0);
  m.map = m.normalMap = m.roughnessMap = m.metalnessMap = m.aoMap = null;
  m.colorNode = vec4(channels.element(0).xyz, alpha);
  m.roughnessNode = channels.element(0).w;
  m.metalnessNode = channels.element(2).x;
  m.normalNode = normalMap(channels.element(1).xyz.mul(0.5).add(0.5), uniform(new Vector2(...scale)));
  m.aoNode = channels.element(1).w;
  // the channels node, for a node graph of your own: columns (base colour, roughness), (normal, occlusion),
  // (metallic)
  m.userData.inshade = {kind: manifest.kind, material: manifest.material, channels};
  return m;
}

// inshade-three.js's applyNetworkMaterial for a WebGPURenderer: every mesh of GLTFLoader's result gltf
// drawn with the file's material manifest.material gets it, shaded by three's own PBR with the
// network's channels per fragment, from its WGSL. Returns the meshes changed; none is an error.
export async function applyNetworkNodeMaterial(gltf, base) {
  const {manifest, textures} = await loadNetworkData(base, false);
  if (manifest.kind !== "material") throw new Error(`${manifest.name}: a ${manifest.kind}, not a glTF material`);
  if (!manifest.wgsl) throw new Error(`${manifest.name}: ${manifest.wgsl_unavailable}`);
  const fn = wgslFn(manifest.wgsl.function, [wgsl(manifest.wgsl.include)]);
  const channels = fn({uv: uv(), ...textureArguments(manifest.wgsl, textures)}).toVar("inshadeChannels");
  return replaceMaterial(gltf, manifest.material, manifest.name,
                         (file, tangents) => decodedNodeMaterial(file, manifest, channels, tangents));
}
