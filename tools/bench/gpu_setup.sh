# Sourced by the device scripts (tools/bench/gpu_bench.sh, tools/bench/gpu_envelope_bench.sh) on a lent
# NVIDIA machine: unpacks the carried GL loader .debs (.gl), installs the carried wheels (.whl:
# moderngl, glcontext, trimesh for the machine's Python), points EGL at NVIDIA's driver and
# checks that a 4.3 context can be made.
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
[ -f /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json ] && \
    export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
export OCC_CACHE_DIR=$PWD/.cache/scenes
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"
nvidia-smi -L
python3 -c "import moderngl; c = moderngl.create_context(standalone=True, backend='egl', require=430); print(c.info['GL_RENDERER'], c.info['GL_VERSION'])" || exit 1
