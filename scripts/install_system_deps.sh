#!/usr/bin/env bash
# Debian packages the project needs, installed only when missing, quietly: apt's output goes to build/setup.log,
# shown only when apt fails. sudo is used when not root.
#   bash scripts/install_system_deps.sh           software OpenGL for offscreen rendering (MUJOCO_GL=osmesa; EGL
#                                                 crashed at random in rollouts here)
#   bash scripts/install_system_deps.sh --test    also what only the tests need: FFmpeg's libraries, with which
#                                                 torchcodec decodes the videos of a LeRobot export
#   bash scripts/install_system_deps.sh PACKAGE...   also these (tests/browser/setup.sh: Chromium)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
log="${SETUP_LOG:-$here/../build/setup.log}"
packages=(libosmesa6 libgl1 libglfw3)
for arg in "$@"; do
  case "$arg" in
    --test) packages+=(ffmpeg) ;;
    *) packages+=("$arg") ;;
  esac
done
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
bash "$here/quietly.sh" "$log" $SUDO apt-get update -qq
bash "$here/quietly.sh" "$log" $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
