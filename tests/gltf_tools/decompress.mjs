// node decompress.mjs IN OUT: IN with its Draco / meshopt compression decoded by glTF Transform
// (draco3d, meshoptimizer) and written as a plain .glb: the reference decode for inshade's reader.
import { NodeIO } from "@gltf-transform/core";
import { ALL_EXTENSIONS } from "@gltf-transform/extensions";
import draco3d from "draco3d";
import { MeshoptDecoder } from "meshoptimizer";

const CODECS = ["KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression"];
const [input, output] = process.argv.slice(2);
await MeshoptDecoder.ready;
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS).registerDependencies({
    "draco3d.decoder": await draco3d.createDecoderModule(),
    "meshopt.decoder": MeshoptDecoder,
});
const doc = await io.read(input);
for (const ext of doc.getRoot().listExtensionsUsed()) {
    if (CODECS.includes(ext.extensionName)) ext.dispose();
}
await io.write(output, doc);
