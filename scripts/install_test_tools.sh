#!/bin/sh
# Install the consuming tools the test suite checks our outputs with, when this machine can:
#   - the Khronos glTF validator (npm gltf-validator) into tools/gltf-validator/ (git-ignored);
#   - Chromium (Debian package `chromium`) for the recording-page and dashboard tests.
# The three.js those pages inline comes from the pip dependency nicegui (docs/serve.md, "The viewer from pip"):
# nothing to build here.
# Each step is skipped when already done. A step that cannot run here (no npm, no apt, no network) prints
# one line and the tests that need it skip, saying why; it never fails `make test`.
# MESHTOOL_NO_SYSTEM=1 (make test SYSTEM=0): no apt-get and no npm download; the tests that need them skip.
set -u
here=$(cd "$(dirname "$0")/.." && pwd)
if [ "${MESHTOOL_NO_SYSTEM:-0}" = "1" ]; then
    [ -f "$here/tools/gltf-validator/node_modules/gltf-validator/package.json" ] \
        || echo "note: MESHTOOL_NO_SYSTEM=1: glTF validator not installed (npm); the GLB validator tests will skip"
    command -v chromium >/dev/null 2>&1 \
        || echo "note: MESHTOOL_NO_SYSTEM=1: Chromium not installed (apt-get); the browser tests will skip"
    exit 0
fi
if [ -f "$here/tools/gltf-validator/node_modules/gltf-validator/package.json" ]; then :; else
    sh "$here/scripts/install_gltf_validator.sh" >/dev/null 2>&1 \
        || echo "note: glTF validator not installed (needs npm); the GLB validator tests will skip"
fi
if command -v chromium >/dev/null 2>&1; then :; else
    sudo=""
    [ "$(id -u)" = 0 ] || sudo="sudo -n"
    if command -v apt-get >/dev/null 2>&1 \
        && $sudo env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=120 install -y -q --no-install-recommends chromium >/dev/null 2>&1; then :
    else
        ($sudo apt-get -o DPkg::Lock::Timeout=120 update -q >/dev/null 2>&1 \
            && $sudo env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=120 install -y -q --no-install-recommends chromium >/dev/null 2>&1) \
            || echo "note: Chromium not installed (apt-get install chromium); the HTML recording tests will skip"
    fi
fi
exit 0
