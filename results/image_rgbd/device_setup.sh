# Sourced by the GPU machine's scripts from the repository root: installs what bundle.sh packed (.gpu/ and the EGL
# loaders in .gl/) and exports the environment veragmil_suite runs in there.
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
egl=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f $egl ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$egl
tar xJf .gpu/site.tar.xz -C /tmp || exit 1
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .gpu/wheels/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD MUJOCO_GL=egl PYOPENGL_PLATFORM=egl PYNPUT_BACKEND=dummy PYTHONUNBUFFERED=1
