#!/usr/bin/env bash
# Install the Debian/Ubuntu packages MuJoCo needs to render headless: EGL through Mesa (libegl1
# libegl-mesa0 libgl1-mesa-dri) AND OSMesa (libosmesa6), whichever are missing.
#
# Idempotent and non-interactive: packages already installed are left alone (no apt-get call at all when
# nothing is missing); apt never prompts. Runs apt-get as root, or through `sudo -n` (never asks for a
# password). Without apt-get, or without the rights, it says what to install and exits 0, so `make demo`
# and CI still run (rendering tests then skip with the reason; `simrun doctor` shows what is there).
# Exit status: 0, or 1 only when an apt-get that ran failed and neither EGL nor OSMesa is there.
# MESHTOOL_NO_SYSTEM=1 (make ... SYSTEM=0): install nothing, only say what is missing.
# A dpkg lock held by another apt (unattended-upgrades) is waited for, up to 120 s.
set -u
PACKAGES="libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6"

missing=""
if command -v dpkg-query >/dev/null 2>&1; then
  for p in $PACKAGES; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
      missing="$missing $p"
    fi
  done
else
  missing=" $PACKAGES"
fi
missing="${missing# }"
if [ -z "$missing" ]; then
  echo "install_gl: EGL and OSMesa packages already installed"
  exit 0
fi
if [ "${MESHTOOL_NO_SYSTEM:-0}" = "1" ]; then
  echo "install_gl: MESHTOOL_NO_SYSTEM=1: not installing $missing (rendering tests will skip without EGL or OSMesa)" >&2
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "install_gl: no apt-get here; install EGL and OSMesa (Mesa) with your package manager: $missing" >&2
  exit 0
fi
if [ "$(id -u)" = "0" ]; then
  as_root=""
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  as_root="sudo -n"
else
  echo "install_gl: not root and no password-less sudo; run: sudo apt-get install -y $missing" >&2
  exit 0
fi
export DEBIAN_FRONTEND=noninteractive
echo "install_gl: installing $missing"
# A stale or unreachable package index is not fatal by itself: the install below says whether it worked.
$as_root apt-get -o DPkg::Lock::Timeout=120 update -qq >/dev/null 2>&1 || echo "install_gl: apt-get update failed; trying the cached index" >&2
# shellcheck disable=SC2086  # word splitting of the package list is wanted
if ! $as_root apt-get -o DPkg::Lock::Timeout=120 install -y -qq --no-install-recommends -o Dpkg::Options::=--force-confold $missing >/dev/null; then
  echo "install_gl: apt-get install failed for: $missing" >&2
  # Still usable when one backend is complete (EGL, or OSMesa): warn, do not stop `make demo`.
  if ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1' || ldconfig -p 2>/dev/null | grep -q 'libOSMesa'; then
    exit 0
  fi
  exit 1
fi
echo "install_gl: installed $missing"
