// An inshade network as a three.js node material for a WebGPURenderer (written by `inshade export-three`
// beside network.json). The network's WGSL, the same code `inshade codegen --target wgsl` writes and
// checks, is the material's colour through TSL's wgslFn:
//
//   import { loadNetworkNodeMesh } from "./my_net/inshade-three-webgpu.js";
//   scene.add(await loadNetworkNodeMesh(new URL("./my_net/", import.meta.url)));   // a 1 x 1 plane
//
// Networks with their weights as literals only (network.json says why another is not taken).
import { Mesh, MeshBasicNodeMaterial, PlaneGeometry } from "three/webgpu";
import { uv, wgsl, wgslFn } from "three/tsl";

// The network's node material: base is the folder's URL (ending in /); the mesh's uv is its input.
export async function loadNetworkNodeMaterial(base) {
  const response = await fetch(new URL("network.json", base));
  if (!response.ok) throw new Error(`network.json: ${response.status} ${response.statusText}`);
  const manifest = await response.json();
  if (manifest.format !== "inshade-three 1") throw new Error(`network.json: format: unknown ${manifest.format}`);
  if (!manifest.wgsl) throw new Error(`${manifest.name}: ${manifest.wgsl_unavailable}`);
  const image = wgslFn(manifest.wgsl.function, [wgsl(manifest.wgsl.include)]);
  const material = new MeshBasicNodeMaterial({transparent: manifest.alpha});
  material.colorNode = image({uv: uv()});
  material.name = manifest.name;
  return material;
}

// The network's picture on a 1 x 1 plane in the xy plane (uv (0, 0) bottom left), facing +z.
export async function loadNetworkNodeMesh(base) {
  const mesh = new Mesh(new PlaneGeometry(1, 1), await loadNetworkNodeMaterial(base));
  mesh.name = mesh.material.name;
  return mesh;
}
