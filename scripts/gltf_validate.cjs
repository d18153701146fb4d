// Validate glTF/GLB files with the Khronos glTF validator installed by scripts/install_gltf_validator.sh.
// Usage: node scripts/gltf_validate.cjs FILE...   Prints one JSON report per line (the validator's own).
const fs = require("fs");
const path = require("path");
const validator = require(path.join(__dirname, "..", "tools", "gltf-validator", "node_modules", "gltf-validator"));

async function main() {
  for (const file of process.argv.slice(2)) {
    const data = new Uint8Array(fs.readFileSync(file));
    const report = await validator.validateBytes(data, {
      uri: path.basename(file),
      maxIssues: 0,
      externalResourceFunction: (uri) =>
        new Promise((resolve, reject) => {
          fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)), (err, d) => (err ? reject(err.toString()) : resolve(new Uint8Array(d))));
        }),
    });
    process.stdout.write(JSON.stringify(report) + "\n");
  }
}
main().catch((e) => { process.stderr.write(String(e) + "\n"); process.exit(2); });
