// node ktx2_decode.mjs IN.ktx2 OUT.rgba: level 0 of a KTX2 (Basis Universal) image transcoded to RGBA8
// by the Basis transcoder three.js ships (npm three, examples/jsm/libs/basis): an independent reading
// for inshade's. OUT holds width, height (uint32 LE) then the rows, top first.
import fs from "node:fs";
import vm from "node:vm";

const dir = new URL("node_modules/three/examples/jsm/libs/basis/", import.meta.url).pathname;
const context = { console };
vm.runInNewContext(fs.readFileSync(dir + "basis_transcoder.js", "utf8") + "\nthis.BASIS = BASIS;", context);
const basis = await context.BASIS({ wasmBinary: fs.readFileSync(dir + "basis_transcoder.wasm") });
basis.initializeBasis();

const [input, output] = process.argv.slice(2);
const file = new basis.KTX2File(new Uint8Array(fs.readFileSync(input)));
if (!file.isValid() || !file.startTranscoding()) throw new Error(`${input}: not a KTX2 file the transcoder reads`);
const width = file.getWidth(), height = file.getHeight();
const RGBA32 = basis.transcoder_texture_format.cTFRGBA32.value;
const out = new Uint8Array(file.getImageTranscodedSizeInBytes(0, 0, 0, RGBA32));
if (!file.transcodeImage(out, 0, 0, 0, RGBA32, 0, -1, -1)) throw new Error(`${input}: transcoding failed`);
file.close();
file.delete();
const head = new Uint32Array([width, height]);
fs.writeFileSync(output, Buffer.concat([Buffer.from(head.buffer), Buffer.from(out.buffer)]));
