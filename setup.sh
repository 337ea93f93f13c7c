#!/usr/bin/env bash
# The one system library krl needs beyond Python: OSMesa, MuJoCo's software OpenGL for offscreen
# rendering (videos, PNG frames) on machines without a display or GPU. Everything else comes from pip.
# Installs Debian/Ubuntu's libosmesa6 when it is missing (with sudo when not root); elsewhere it says
# what to install. Rendering is optional: without the library every command but the rendering ones works.
set -euo pipefail
if ldconfig -p 2>/dev/null | grep -q 'libOSMesa\.so'; then
  echo "setup: libOSMesa is installed"
  exit 0
fi
if command -v apt-get >/dev/null 2>&1; then
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  echo "setup: installing libosmesa6 (offscreen rendering) with apt-get"
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq libosmesa6 >/dev/null
  echo "setup: libOSMesa is installed"
else
  echo "setup: no apt-get here; for offscreen rendering install your system's OSMesa library" \
    "(Fedora: mesa-libOSMesa, Arch: mesa) or render with MUJOCO_GL=egl on a GPU" >&2
fi
