// Validate GLB files with the Khronos glTF Validator (npm gltf-validator): prints one JSON line
// per file: {"file", "errors", "warnings", "infos", "hints", "messages": [{code, severity,
// message, pointer}]} (severity 0 error, 1 warning, 2 info, 3 hint). Exit code 0 when every
// file was read, whatever it reports; the caller judges the counts.
//   node tools/validate-gltf.mjs FILE.glb [FILE.glb ...]
import { readFileSync } from 'node:fs';
import { basename } from 'node:path';
import validator from 'gltf-validator';

for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    uri: basename(file),
    maxIssues: 0, // all of them
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
  });
  const issues = report.issues;
  console.log(JSON.stringify({
    file,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    infos: issues.numInfos,
    hints: issues.numHints,
    messages: issues.messages.map(({ code, severity, message, pointer }) => ({ code, severity, message, pointer })),
  }));
}
