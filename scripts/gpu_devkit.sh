#!/usr/bin/env bash
# Packs what a GPU machine without a Rust toolchain needs to run the collision
# benchmark and a real-brain replay per backend (how the README's H100 table was
# made): the stripped release binary, the shared libraries it and NVIDIA's Vulkan
# driver load (copied from this machine; x86-64 Linux with glibc >= this one's)
# and run.sh. The folder is .devkit/ (git ignores it); about 40 MB. The real
# brains travel with the repository (assets/brain/).
#
#   bash scripts/gpu_devkit.sh            # build and pack
#   # on the GPU machine, in a copy of the repository with .devkit/ beside it:
#   REPLAY=1 SYLVIAN=1 bash .devkit/run.sh   # writes $OUT/bench.md (OUT defaults to /tmp/fissure-gpu)
#   NO_BENCH=1 SYLVIAN=1 bash .devkit/run.sh # only the fine brain's replays and picture
set -euo pipefail
cd "$(dirname "$0")/.."
kit=.devkit
cargo build --release
rm -rf "$kit" && mkdir -p "$kit/lib"
strip -o "$kit/fissure" target/release/fissure
# The binary's own libraries, then the GL dispatch libraries NVIDIA's Vulkan ICD
# (libGLX_nvidia.so.0) needs: without them the loader finds the ICD but not
# vkCreateInstance, and wgpu reports no adapter.
libs=$(ldd target/release/fissure | awk '/=> \//{print $3}' | grep -v -E '/(libc|libm|libgcc_s|ld-linux)[.-]')
for name in libvulkan.so.1 libGLdispatch.so.0 libGLX.so.0 libGL.so.1 libEGL.so.1 libOpenGL.so.0 libX11.so.6 libXext.so.6 libxcb.so.1 libXau.so.6 libXdmcp.so.6 libbsd.so.0 libmd.so.0; do
    # awk reads to the end: leaving early would end ldconfig by SIGPIPE, which
    # pipefail turns into this script's exit.
    path=$(ldconfig -p | awk -v n="$name" '$1 == n && /x86-64/ && !p {print $NF; p = 1}')
    if [ -z "$path" ]; then
        echo "error: $name is not installed here (apt-get install the package that has it, e.g. libvulkan1, libglvnd0, libx11-6)" >&2
        exit 1
    fi
    libs="$libs $path"
done
for l in $libs; do cp -L "$l" "$kit/lib/"; done
cat > "$kit/run.sh" <<'EOF'
#!/usr/bin/env bash
# The collision bench on every backend in one run (so their ratio is fair), then
# with REPLAY=1 the coarse real brain's replay with collision.backend Bvh, Gpu, Auto.
R=$(pwd); K=$R/.devkit; OUT=${OUT:-/tmp/fissure-gpu}; mkdir -p "$OUT" /tmp/xdg
export LD_LIBRARY_PATH=$K/lib XDG_RUNTIME_DIR=/tmp/xdg RUST_LOG=${RUST_LOG:-error,fissure=warn}
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json}
chmod +x "$K/fissure"
nvidia-smi -L 2>/dev/null; nproc
ldd "$K/fissure" | grep "not found"
if [ -z "${NO_BENCH:-}" ]; then
    time "$K/fissure" bench collision --mesh-dir "$R/assets/brain" --frames "${FR:-60}" --out "$OUT/bench.md" > "$OUT/bench.log" 2>&1; echo "bench rc $?"
    cat "$OUT/bench.log"
fi
# A scene's replay with each collision backend: per_backend SCENARIO TAG
# (prints each run's times and backend, keeps each summary as $OUT/TAG_BACKEND.json).
per_backend() {
    for b in Bvh Gpu Auto; do
        rm -rf /tmp/fissure-replay
        "$K/fissure" replay "$1" \
            --set 'solver.cache_dir=Some("/tmp/fissure-cache")' --set collision.backend=$b --out /tmp/fissure-replay > /tmp/fissure-replay.log 2>&1
        echo "$2 $b rc $?"; grep -E "collision|frame time|backend|final state" /tmp/fissure-replay.log | head -6
        cp /tmp/fissure-replay/summary.json "$OUT/$2_$b.json" 2>/dev/null
    done
}
if [ -n "${REPLAY:-}" ]; then
    per_backend config/real_brain/interhemispheric.ron summary
fi
# With SYLVIAN=1: the fine brain's Sylvian opening (the scene the window ships,
# refined under the blades) with each backend, and one screenshot on the GPU.
if [ -n "${SYLVIAN:-}" ]; then
    per_backend config/real_brain/sylvian.ron sylvian
    "$K/fissure" screenshot config/real_brain/sylvian.ron \
        --set 'solver.cache_dir=Some("/tmp/fissure-cache")' --time 4 --view microscope --field pressure -o "$OUT/sylvian_microscope.png" 2>&1 | tail -3
fi
EOF
chmod +x "$kit/run.sh"
du -sh "$kit"
