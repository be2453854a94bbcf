#!/usr/bin/env bash
# Packs what the GPU machine lacks (its image has torch, numpy, scipy, numba, h5py, cv2, Pillow, PyYAML) into
# .gpu/: the pure-Python packages from this venv (robosuite with only the xArm7, mount and texture assets the
# scene loads) and diffusers, MuJoCo's wheel for Python 3.12, and .gl/ the EGL loaders (libglvnd), as the device
# tool's README says. Run from the repository root with the venv active.
set -euo pipefail
SITE=$(python -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
rm -rf .gpu/site && mkdir -p .gpu/site .gpu/wheels .gl
for pkg in OpenGL dill farama_notifications glfw gymnasium robomimic termcolor tensorboardX; do
    cp -r "$SITE/$pkg" .gpu/site/
done
( cd "$SITE" && find robosuite robosuite_models -name '*.py' -o -name '*.xml' -o -name '*.json' -o -name '*.yaml' \
    | grep -v __pycache__ | tar cf - -T - ) | tar xf - -C .gpu/site
python - <<'PY'
import os, re, shutil, robosuite, veragmil_suite
env = robosuite.make("ScoopGranular", has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
site = os.path.dirname(os.path.dirname(robosuite.__file__))
for f in sorted(set(re.findall(r'file="([^"]+)"', env.model.get_xml()))):
    f = os.path.realpath(f)
    if f.startswith(site):
        dest = os.path.join(".gpu/site", os.path.relpath(f, site))
        os.makedirs(os.path.dirname(dest), exist_ok=True)
        shutil.copy(f, dest)
PY
pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 -d .gpu/wheels mujoco==3.8.1 diffusers==0.42.1
# diffusers is pure Python: unpacked into the xz archive it takes 4 MiB less of the 64 MiB than its wheel
pip install -q --no-deps --no-compile --target .gpu/site .gpu/wheels/diffusers-*.whl && rm .gpu/wheels/diffusers-*.whl
find .gpu/site -name __pycache__ -prune -exec rm -rf {} +
tar cJf .gpu/site.tar.xz -C .gpu site && rm -rf .gpu/site
mkdir -p /tmp/amd64/partial
o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
apt-get $o update -qq && (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
du -sh .gpu .gl
