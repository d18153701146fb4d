#!/bin/sh
# Install three.js (npm package `three`) and bundle the parts simrun's recording pages use (the WebGL
# renderer, GLTFLoader, OrbitControls) with esbuild into tools/three-viewer/dist/viewer.js (git-ignored).
# `simrun replay --html` inlines that file into each page, so the page works offline from a file:// URL.
# Versions are pinned: the same bundle, byte for byte, on every machine. Set SIMRUN_VIEWER_JS to use a
# bundle elsewhere. The HTML tests skip, saying why, without it.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
target="$here/tools/three-viewer"
command -v npm >/dev/null 2>&1 || { echo "error: npm not found (install Node.js 18 or newer)" >&2; exit 1; }
mkdir -p "$target"
cd "$target"
[ -f package.json ] || printf '{"name": "simrun-three-viewer", "private": true}\n' > package.json
npm install --no-audit --no-fund --save-exact three@0.187.0 esbuild@0.28.2
cp "$here/scripts/three_viewer_entry.js" entry.js
./node_modules/.bin/esbuild entry.js --bundle --format=iife --minify --legal-comments=eof --log-level=warning \
    --outfile=dist/viewer.js
echo "bundled three $(node -p "JSON.parse(require(\"fs\").readFileSync(\"node_modules/three/package.json\")).version") into $target/dist/viewer.js"
