// node validate.mjs FILE...: one JSON line per file with the Khronos validator's verdict
// ({file, errors, warnings, messages: [code, pointer, message] of errors and warnings}).
import fs from "node:fs";
import path from "node:path";
import validator from "gltf-validator";

for (const file of process.argv.slice(2)) {
    const bytes = new Uint8Array(fs.readFileSync(file));
    const report = await validator.validateBytes(bytes, {
        uri: path.basename(file),
        externalResourceFunction: (uri) => new Promise((resolve, reject) => {
            fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)),
                        (err, data) => err ? reject(err.toString()) : resolve(new Uint8Array(data)));
        }),
    });
    const issues = report.issues;
    console.log(JSON.stringify({
        file, errors: issues.numErrors, warnings: issues.numWarnings,
        messages: issues.messages.filter((m) => m.severity <= 1).map((m) => [m.code, m.pointer, m.message]),
    }));
}
