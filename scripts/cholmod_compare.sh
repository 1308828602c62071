#!/usr/bin/env bash
# Our sparse Cholesky beside CHOLMOD's on the same matrix (the bars: factor
# and solve <= 1.0x CHOLMOD's time, nnz(L) within 10 % of CHOLMOD with METIS):
# the stiffness K_FF of each shipped real brain in assets/brain (as the fem
# bench builds it), factored by fissure (examples/factor_compare.rs) and by
# CHOLMOD (scripts/cholmod_compare.c), each with METIS and with AMD, one
# thread, alternating ROUNDS times (default 3) so both see the same machine.
# Needs CHOLMOD and an optimised BLAS (Debian: apt-get install
# libsuitesparse-dev libopenblas0-pthread); not part of the tests.
# Usage: bash scripts/cholmod_compare.sh [MESH.msh ...]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${ROUNDS:-3}"
header=/usr/include/suitesparse/cholmod.h
if [ ! -f "$header" ]; then
    echo "cholmod_compare: $header not found; install CHOLMOD (Debian: apt-get install libsuitesparse-dev libopenblas0-pthread)" >&2
    exit 1
fi
work=target/cholmod-compare
mkdir -p "$work"
cc -O2 scripts/cholmod_compare.c -I/usr/include/suitesparse -lcholmod -lm -o "$work/cholmod_compare"
cargo build --release --quiet --example factor_compare
meshes=("$@")
if [ ${#meshes[@]} -eq 0 ]; then
    meshes=(assets/brain/brain_pial_coarse.msh.gz assets/brain/brain_pial_q15.msh.gz)
fi
# OpenBLAS picks its kernels from the CPU's model; a virtual CPU that names no
# model ("Intel Xeon Processor") gets the generic Prescott kernels, 1.3-1.6x
# slower here than the AVX-512 ones the CPU has. Name the kernel from the CPU's
# flags unless the caller chose one.
if [ -z "${OPENBLAS_CORETYPE:-}" ]; then
    if grep -qw avx512f /proc/cpuinfo; then export OPENBLAS_CORETYPE=SkylakeX
    elif grep -qw avx2 /proc/cpuinfo; then export OPENBLAS_CORETYPE=Haswell
    fi
fi
echo "BLAS: $(readlink -f /usr/lib/x86_64-linux-gnu/libblas.so.3 2>/dev/null || echo unknown), OpenBLAS kernels ${OPENBLAS_CORETYPE:-as detected}; CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
for mesh in "${meshes[@]}"; do
    name=$(basename "$mesh"); name=${name%.gz}; name=${name%.msh}
    echo "== $name"
    for round in $(seq 1 "$rounds"); do
        echo "-- round $round"
        target/release/examples/factor_compare "$mesh" "$work/$name.mtx"
        for method in metis amd; do
            OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 "$work/cholmod_compare" "$work/$name.mtx" "$method"
        done
    done
done
