#!/usr/bin/env bash
# What tests/test_vr_browser.py needs: Debian's chromium (+ chromium-driver), Node.js >= 18 with npm (Debian 12's
# own nodejs is enough), and the npm packages pinned in package-lock.json (playwright-core 1.61, the last for
# Node 18, drives /usr/bin/chromium; iwer is Meta's WebXR emulator). Installs only what is missing; sudo is used
# when not root.
set -euo pipefail
cd "$(dirname "$0")"

packages=(chromium chromium-driver)
command -v node >/dev/null && command -v npm >/dev/null || packages+=(nodejs npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

npm ci --no-audit --no-fund
