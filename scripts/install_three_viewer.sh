#!/bin/sh
# Optional: build another three.js viewer bundle from npm, for SIMRUN_VIEWER_JS. simrun does not need it:
# the dashboard and `simrun replay --html` inline the three.js module of the pip dependency nicegui
# (docs/serve.md, "The viewer from pip"), and neither `make test` nor `make demo` runs this script.
# It installs three.js (npm package `three`) and bundles the parts the pages use (the WebGL renderer,
# GLTFLoader, OrbitControls) with esbuild into tools/three-viewer/dist/viewer.js (git-ignored), e.g. to try
# a newer three.js: SIMRUN_VIEWER_JS=tools/three-viewer/dist/viewer.js simrun replay RUN.simlog --html RUN.html
# Versions are pinned: the same bundle, byte for byte, on every machine.
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
