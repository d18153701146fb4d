#!/usr/bin/env bash
# Install the Debian packages MuJoCo needs to render headless (EGL through Mesa, and OSMesa), when missing.
# Safe to run repeatedly; does nothing without root or apt-get (camera tests then skip with the reason).
set -u
if ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1'; then
  exit 0
fi
if [ "$(id -u)" != "0" ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "install_gl: not root or no apt-get; skipping (headless rendering tests will be skipped)" >&2
  exit 0
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >/dev/null 2>&1 || true
apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6 >/dev/null 2>&1 \
  || echo "install_gl: apt-get install failed; headless rendering tests will be skipped" >&2
exit 0
