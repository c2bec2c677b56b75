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
// A glTF material a network decodes (inshade train di_pbr_set --gltf FILE) goes onto your own glTF
// scene, as GLTFLoader gives it: `await applyNetworkMaterial(gltf, base)`.
// Texels are data: no colour space, no flip, no mipmaps generated.
import * as THREE from "three";
import { loadNetworkData, replaceMaterial } from "./inshade-three-data.js";

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

// A flat tangent-space normal map: it turns three's normal-map path on (the tangent frame, normalScale),
// whose texel the network's normal replaces
const FLAT_NORMAL = new THREE.DataTexture(new Uint8Array([128, 128, 255, 255]), 1, 1);
FLAT_NORMAL.needsUpdate = true;

// three's shader chunks -> what reads the network's channels instead of the maps: [chunk, replacement];
// `channels` (MaterialChannels, declared at the first) holds them. A chunk whose text is edited is
// three's own with one read replaced, found exactly once (else an error naming three's revision).
const READS = [
  ["map_fragment", () => "MaterialChannels channels = three_material_channels( vUv );\n" +
    "#ifdef USE_MAP\n\tdiffuseColor.a *= texture2D( map, vMapUv ).a;\n#endif\n" +
    "diffuseColor.rgb = channels.base_color;"],
  ["roughnessmap_fragment", () => "float roughnessFactor = channels.roughness;"],
  ["metalnessmap_fragment", () => "float metalnessFactor = channels.metallic;"],
  ["normal_fragment_maps", () => edited("normal_fragment_maps", [
    ["vec3 mapN = texture2D( normalMap, vNormalMapUv ).xyz * 2.0 - 1.0;", "vec3 mapN = channels.normal;"]])],
  ["aomap_fragment", () => edited("aomap_fragment", [
    ["#ifdef USE_AOMAP", "#if 1"],
    ["float ambientOcclusion = ( texture2D( aoMap, vAoMapUv ).r - 1.0 ) * aoMapIntensity + 1.0;",
     "float ambientOcclusion = channels.occlusion;"]])],
];

function edited(chunk, edits) {
  let text = THREE.ShaderChunk[chunk];
  for (const [from, to] of edits) {
    const found = text.split(from).length - 1;
    if (found !== 1) throw new Error(`three ${THREE.REVISION}: ${chunk} has "${from}" ${found} times, not once`);
    text = text.replace(from, () => to);
  }
  return text;
}

// The file's material `file` with the network's channels in place of its maps (base colour, roughness,
// metalness, normal map, occlusion); its other parts (emission, clearcoat, sheen, ...) stay the file's.
// tangents: the mesh has a tangent attribute (else three derives the frame and GLTFLoader flips y).
function decodedMaterial(file, manifest, uniforms, tangents) {
  const m = file.clone();
  m.name = `${file.name} (${manifest.name})`;
  if (m.normalMap) m.normalScale.set(Math.sign(m.normalScale.x) || 1, Math.sign(m.normalScale.y) || 1);
  else m.normalScale.set(1, tangents ? 1 : -1);   // the decoded normal is at full strength already
  m.normalMap = FLAT_NORMAL;
  m.roughnessMap = m.metalnessMap = m.aoMap = null;
  if (!(m.transparent || m.alphaTest > 0)) m.map = null;   // the base colour map is kept for its alpha only
  m.defines = {...m.defines, USE_UV: ""};
  m.onBeforeCompile = (shader) => {
    Object.assign(shader.uniforms, uniforms);
    let text = shader.fragmentShader.replace("void main() {", () => `${manifest.declarations}\nvoid main() {`);
    for (const [chunk, replacement] of READS) {
      const include = `#include <${chunk}>`;
      if (text.split(include).length !== 2) {
        throw new Error(`three ${THREE.REVISION}: ${include} is not in the program once`);
      }
      text = text.replace(include, replacement);
    }
    shader.fragmentShader = text;
  };
  m.customProgramCacheKey = () => `inshade:${manifest.bundle_digest}`;
  m.userData.inshade = {kind: manifest.kind, material: manifest.material};
  return m;
}

// A glTF material decoded by the network, on your glTF scene: gltf is GLTFLoader's result (its parser
// says which material is which); every mesh drawn with the file's material manifest.material gets it,
// shaded by three's own PBR (MeshStandardMaterial / MeshPhysicalMaterial) with the network's base
// colour, roughness, metalness, normal map and occlusion per fragment at the mesh's uv (TEXCOORD_0).
// Returns the meshes changed; none is an error.
export async function applyNetworkMaterial(gltf, base) {
  const {manifest, textures} = await loadNetworkData(base, true);
  if (manifest.kind !== "material") throw new Error(`${manifest.name}: a ${manifest.kind}, not a glTF material`);
  const uniforms = Object.fromEntries(textures(manifest.textures).map(([name, value]) => [name, {value}]));
  return replaceMaterial(gltf, manifest.material, manifest.name,
                         (file, tangents) => decodedMaterial(file, manifest, uniforms, tangents));
}
