// SPIR-V modules -> WGSL with naga (npm naga-wasm): `node naga.mjs` reads a JSON list of
// [spirv_path, wgsl_path] pairs on stdin, writes each WGSL file and prints one JSON line per pair:
// {"uniforms": [...]} (each uniform buffer's members where WGSL places them, read back from the WGSL
// by wgsl_reflect: a std140 array of scalars keeps its 16-byte stride in SPIR-V but not in the WGSL
// naga writes) or {"error": "..."}; one process for every program of a page.
import { parseSpirv, validate, writeWgsl } from "naga-wasm";
import { WgslReflect } from "wgsl_reflect/wgsl_reflect.module.js";
import { readFileSync, writeFileSync } from "fs";

const member = (m) => ({name: m.name, offset: m.offset, size: m.size, stride: m.type.stride ?? null,
                        count: m.type.count ?? null});

const pairs = JSON.parse(readFileSync(0, "utf8"));
for (const [spirv, wgsl] of pairs) {
  try {
    const module = parseSpirv(new Uint8Array(readFileSync(spirv)));
    const code = writeWgsl(module, validate(module), {});
    writeFileSync(wgsl, code);
    const uniforms = new WgslReflect(code).uniforms.map((u) => ({group: u.group, binding: u.binding, size: u.size,
                                                                  members: (u.type.members || []).map(member)}));
    console.log(JSON.stringify({uniforms}));
  } catch (e) {
    console.log(JSON.stringify({error: `${e.kind || "error"}: ${e.message}\n${(e.formatted || "").slice(0, 2000)}`}));
  }
}
