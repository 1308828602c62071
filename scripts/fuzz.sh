#!/usr/bin/env bash
# Bounded cargo-fuzz run over every entrance target (fuzz/fuzz_targets/*).
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET]   (default 30; e.g. 120 for a 10-minute run of 5 targets)
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`). cargo-fuzz uses nightly-only
# rustc flags; on the stable toolchain RUSTC_BOOTSTRAP=1 allows them. The
# sanitizer is off (`-s none`): the crate is safe Rust, and what we look for is
# panics, hangs (-timeout) and runaway allocation (-rss_limit_mb /
# -malloc_limit_mb). Seeds come from config/*.ron and the test data, so the
# fuzzer starts from valid inputs. Exit status: non-zero when a target finds a
# crash (its input is left under fuzz/artifacts/<target>/).
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
SECONDS_PER_TARGET="${1:-30}"
export RUSTC_BOOTSTRAP=1
TARGETS=(mesh_parsers scenario trajectory igtl spacemouse)

# Seed corpora from valid inputs (idempotent).
mkdir -p corpus/mesh_parsers corpus/scenario corpus/trajectory corpus/igtl corpus/spacemouse
# A SpaceMouse seed: a spacenavd motion event (type 0, six axes, period) then HID reports 1, 2 and 3.
printf '\x00\x00\x00\x00\x78\x00\x00\x00\xdd\xff\xff\xff\xc8\x00\x00\x00\xf6\xff\xff\xff\x06\xff\xff\xff\xc4\xff\xff\xff\x10\x00\x00\x00\x07\x01\x78\x00\x38\xff\x23\x00\x07\x02\xf6\xff\x3c\x00\xfa\x00\x03\x03\x01\x00' > corpus/spacemouse/seed
for f in ../config/*.ron; do cp -f "$f" "corpus/scenario/$(basename "$f")"; done
printf 'time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0.0,0,1.5,-2.0,3.0,1.0,0.0,0.0,0.0\n0.5,1,1.5,-2.0,3.0,0.7071067811865476,0.7071067811865476,0.0,0.0\n' > corpus/trajectory/seed.csv
for f in ../assets/trajectories/*.csv; do [ -e "$f" ] && cp -f "$f" "corpus/trajectory/$(basename "$f")"; done
# Mesh seeds: the selector byte (0 gmsh, 1 vtk, 2 vtu, 3 tetgen node, 4 tetgen ele, 5 obj, 6 stl) then the file.
printf '\x03' > corpus/mesh_parsers/node; printf '5 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n' >> corpus/mesh_parsers/node
printf '\x04' > corpus/mesh_parsers/ele; printf '2 4 0\n1 1 2 3 4\n2 2 3 5 4\n' >> corpus/mesh_parsers/ele
printf '\x05v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > corpus/mesh_parsers/obj
printf '\x00$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 2 1 1 1 2 3 4\n$EndElements\n' > corpus/mesh_parsers/msh
printf '\x01# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0\n1 0 0\n0 1 0\n0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n' > corpus/mesh_parsers/vtk
python3 - <<'PY'
# One valid TRANSFORM (header v1) for the igtl corpus, built like igtl_codec::encode_transform.
import struct
def crc64(b):
    poly = 0x42F0E1EBA9EA3693; crc = 0
    for byte in b:
        crc ^= byte << 56
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFFFFFFFFFFFFFFFF if crc & (1 << 63) else (crc << 1) & 0xFFFFFFFFFFFFFFFF
    return crc
body = struct.pack('>12f', 1, 0, 0, 0, 1, 0, 0, 0, 1, 10, 20, 30)
head = struct.pack('>H12s20sQQQ', 1, b'TRANSFORM', b'Left', 0, len(body), crc64(body))
open('corpus/igtl/transform', 'wb').write(head + body)
PY

status=0
mkdir -p target
for t in "${TARGETS[@]}"; do
    echo "== $t: ${SECONDS_PER_TARGET} s"
    set +e
    cargo fuzz run -s none -O "$t" -- -max_total_time="$SECONDS_PER_TARGET" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 -print_final_stats=1 > "target/fuzz-$t.log" 2>&1
    rc=$?
    set -e
    grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb|^Done [0-9]+ runs|panicked|SUMMARY|crash-|timeout-|oom-" "target/fuzz-$t.log" || true
    if [ $rc -ne 0 ]; then
        echo "!! $t exited with $rc (log: fuzz/target/fuzz-$t.log)"
        status=1
    fi
done
exit $status
