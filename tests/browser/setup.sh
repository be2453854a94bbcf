#!/usr/bin/env bash
# What tests/test_vr_browser.py needs: Debian's chromium (+ chromium-driver), Node.js >= 18 with npm (Debian 12's
# own nodejs is enough), and the npm packages pinned in package-lock.json (playwright-core 1.61, the last for
# Node 18, drives /usr/bin/chromium; iwer is Meta's WebXR emulator). Installs only what is missing, quietly
# (scripts/install_system_deps.sh); make test runs it.
set -euo pipefail
cd "$(dirname "$0")"

packages=(chromium chromium-driver)
command -v node >/dev/null && command -v npm >/dev/null || packages+=(nodejs npm)
bash ../../scripts/install_system_deps.sh "${packages[@]}"
bash ../../scripts/quietly.sh "${SETUP_LOG:-../../build/setup.log}" npm ci --no-audit --no-fund
