#!/usr/bin/env bash
# Debian packages the project needs: software OpenGL for offscreen rendering (MUJOCO_GL=osmesa; EGL crashed at
# random in rollouts here), and Chromium for the WebXR page's end-to-end test. Installs only what is missing.
set -euo pipefail
packages=(libosmesa6 libgl1 libglfw3 chromium chromium-driver)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
