// Validates glTF and GLB files with the Khronos glTF validator (npm package
// `gltf-validator`, found through NODE_PATH): prints each file's counts and its errors and
// warnings; exits 1 when any file has an error, 2 when the validator itself fails.
// Usage: NODE_PATH=target/node/node_modules node scripts/gltf-validate.js FILE…
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

async function validate(file) {
  const dir = path.dirname(file);
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        try {
          resolve(new Uint8Array(fs.readFileSync(path.join(dir, decodeURIComponent(uri)))));
        } catch (e) {
          reject(e.toString());
        }
      }),
  });
  const i = report.issues;
  console.log(`${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos`);
  for (const m of i.messages) {
    if (m.severity <= 1) {
      const kind = m.severity === 0 ? 'error' : 'warning';
      console.log(`  ${kind} ${m.code}: ${m.message} ${m.pointer || ''}`);
    }
  }
  return i.numErrors === 0;
}

(async () => {
  let ok = true;
  for (const file of process.argv.slice(2)) {
    ok = (await validate(file)) && ok;
  }
  process.exit(ok ? 0 : 1);
})().catch((e) => {
  console.error(e);
  process.exit(2);
});
