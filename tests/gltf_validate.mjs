// Validates a glTF 2.0 file (.glb or .gltf) with the Khronos glTF validator
// (npm package gltf-validator, installed by ./build.sh with `npm ci`).
//   node tests/gltf_validate.mjs [--strict] FILE...
// Prints every issue and one summary line per file:
//   FILE: E errors, W warnings, I infos, H hints
// Exit status: 0 valid, 1 some file has an error (or, with --strict, a
// warning), 2 bad usage or a file that cannot be read.
import fs from 'node:fs';
import path from 'node:path';
import validator from 'gltf-validator';

const SEVERITY = ['error', 'warning', 'info', 'hint'];

const args = process.argv.slice(2);
const strict = args.includes('--strict');
const files = args.filter((a) => a !== '--strict');
if (files.length === 0) {
    console.error('usage: node tests/gltf_validate.mjs [--strict] FILE...');
    process.exit(2);
}

let status = 0;
for (const file of files) {
    let bytes;
    try {
        bytes = new Uint8Array(fs.readFileSync(file));
    } catch (e) {
        console.error(`${file}: cannot read: ${e.message}`);
        status = Math.max(status, 2);
        continue;
    }
    const report = await validator.validateBytes(bytes, {
        uri: path.basename(file),
        maxIssues: 0, // report every issue
        externalResourceFunction: (uri) =>
            new Promise((resolve, reject) => {
                fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
                    err ? reject(err.toString()) : resolve(new Uint8Array(data)));
            }),
    });
    const is = report.issues;
    for (const m of is.messages)
        console.log(`${file}: ${SEVERITY[m.severity] ?? m.severity}: ${m.code}: ${m.message}` +
                    (m.pointer ? ` (at ${m.pointer})` : ''));
    console.log(`${file}: ${is.numErrors} errors, ${is.numWarnings} warnings, ${is.numInfos} infos, ${is.numHints} hints`);
    if (is.numErrors > 0 || (strict && is.numWarnings > 0)) status = Math.max(status, 1);
}
process.exit(status);
