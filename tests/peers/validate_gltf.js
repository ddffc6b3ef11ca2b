// Validates one glTF/GLB file with the Khronos glTF validator and prints
// its issue summary (numErrors, numWarnings, numInfos, numHints, messages)
// as one JSON line. Exit 3 when the validator is not installed.
const fs = require('fs');
let validator;
try {
  validator = require('gltf-validator');
} catch (e) {
  console.error('gltf-validator is not installed: run `npm install --prefix tests/peers`');
  process.exit(3);
}
const file = process.argv[2];
const data = new Uint8Array(fs.readFileSync(file));
validator
  .validateBytes(data, { maxIssues: 200 })
  .then((report) => {
    console.log(JSON.stringify(report.issues));
  })
  .catch((e) => {
    console.error(String(e));
    process.exit(2);
  });
