#!/bin/sh
# Install the Khronos glTF validator (npm package gltf-validator) under tools/gltf-validator/ (git-ignored).
# The GLB tests run it through node; they skip, saying why, when node or the package is absent.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
target="$here/tools/gltf-validator"
command -v npm >/dev/null 2>&1 || { echo "error: npm not found (install Node.js 18 or newer)" >&2; exit 1; }
mkdir -p "$target"
cd "$target"
[ -f package.json ] || printf '{"name": "meshtool-gltf-validator", "private": true}\n' > package.json
npm install --no-audit --no-fund --save-exact gltf-validator@2.0.0-dev.3.10
echo "installed $(node -e 'console.log(require("gltf-validator").version())') in $target"
