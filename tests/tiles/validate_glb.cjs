// Runs the Khronos glTF validator (npm gltf-validator) over every glb under a folder and prints one
// JSON line per file with its error and warning counts and the first messages; exits 1 when any
// file has an error. NODE_PATH names the folder the npm packages were installed in.
//   node validate_glb.cjs DIR
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

function glbFiles(dir) {
  const out = [];
  for (const entry of fs.readdirSync(dir, { withFileTypes: true })) {
    const p = path.join(dir, entry.name);
    if (entry.isDirectory()) out.push(...glbFiles(p));
    else if (entry.name.endsWith('.glb')) out.push(p);
  }
  return out.sort();
}

(async () => {
  let failed = 0;
  const files = glbFiles(process.argv[2]);
  for (const file of files) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), { uri: file, maxIssues: 20 });
    const errors = report.issues.numErrors, warnings = report.issues.numWarnings;
    if (errors) failed++;
    const messages = report.issues.messages.filter((m) => m.severity <= 1).slice(0, 3).map((m) => `${m.code}: ${m.message}`);
    console.log(JSON.stringify({ file: path.basename(file), errors, warnings, messages }));
  }
  console.log(JSON.stringify({ files: files.length, failed }));
  process.exit(failed || files.length === 0 ? 1 : 0);
})();
