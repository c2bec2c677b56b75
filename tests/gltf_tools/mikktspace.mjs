// node mikktspace.mjs IN.bin OUT.bin: MikkTSpace tangents of a triangle soup. IN: float32
// [n corners] x (position 3, normal 3, uv 2) (uv as glTF stores them); OUT: float32 [n, 4].
import fs from "node:fs";
import { generateTangents } from "mikktspace";

const raw = fs.readFileSync(process.argv[2]);
const data = new Float32Array(raw.buffer, raw.byteOffset, raw.byteLength / 4);
const n = data.length / 8;
const pos = new Float32Array(3 * n), nrm = new Float32Array(3 * n), uv = new Float32Array(2 * n);
for (let i = 0; i < n; i++) {
    pos.set(data.subarray(8 * i, 8 * i + 3), 3 * i);
    nrm.set(data.subarray(8 * i + 3, 8 * i + 6), 3 * i);
    uv.set(data.subarray(8 * i + 6, 8 * i + 8), 2 * i);
}
fs.writeFileSync(process.argv[3], Buffer.from(generateTangents(pos, nrm, uv).buffer));
