#!/usr/bin/env bash
# What each optimisation of fem/ buys, measured again on today's code and
# machine (docs/design-notes.md says what each optimisation of fem/ buys). Every one can be switched off (`fem::tuning`,
# FISSURE_FEM_OFF=name); on and off run alternately on the same machine.
#  1. the per-frame switches and the row-major solve, in the fem bench:
#     `cargo bench --bench fem -- audit paper coarse` (paper-12k and the
#     coarse real brain);
#  2. huge pages under the compliance: the same bench's held and sliding
#     product lines with FISSURE_FEM_OFF=huge-pages (paper-12k);
#  3. the scene-level switches (candidate blocks, W factor reuse, the
#     candidate screen and its records kept across frames, W's entries kept across the active-set iterations,
#     tethers read through their own columns; SWITCHES="a b" picks some; the screen's wide-press figures come from
#     `TRAJ=assets/trajectories/real_brain_sylvian_wide.csv cargo run --release
#     --example stall_probe -- config/real_brain/sylvian.ron 100 duration_s=4.5`)
#     on whole replays, ROUNDS rounds (default 2) alternating: the default
#     scene and the fine-brain Sylvian opening from
#     its cache (the first replay of a scene writes the cache and is not
#     counted).
# Not part of the tests (about 20 minutes on 2 cores).
# Usage: bash scripts/fem_audit.sh [SCENE.ron ...]  (PARTS="2 3" runs some parts)
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${ROUNDS:-2}"
parts="${PARTS:-1 2 3}"
models=(paper coarse)

if [[ " $parts " == *" 1 "* ]]; then
    echo "== 1. per-frame switches (cargo bench --bench fem -- audit ${models[*]})"
    cargo bench --quiet --bench fem -- audit "${models[@]}" 2>/dev/null | grep -E '^(== |audit)'
fi
if [[ " $parts " == *" 2 "* ]]; then
    # Huge pages are taken when the compliance is computed, so on and off are
    # two processes: ROUNDS rounds, alternating which goes first. The figure is
    # the surface product with every other switch on (the first number of
    # each product line), held / growing / sliding.
    echo "== 2. huge pages, $rounds rounds alternating (cargo bench --bench fem -- audit paper, with and without FISSURE_FEM_OFF=huge-pages): surface product held / growing / sliding, ms"
    products() { # OFF -> "held growing sliding" (medians over the four product switches' 'on' runs)
        FISSURE_FEM_OFF="$1" cargo bench --quiet --bench fem -- audit paper 2>/dev/null \
            | grep -E '^audit (kept-product-rows|fused-columns|row-chunks|avx2-product)' \
            | python3 -c '
import re, statistics, sys
v = {}
for line in sys.stdin:
    m = re.match(r"audit +[a-z0-9-]+ +([a-z]+) *:.*surface product ([0-9.]+) ->", line)
    if m:
        v.setdefault(m[1], []).append(float(m[2]))
print(" / ".join(f"{statistics.median(v[k]):.2f}" if k in v else "n/a" for k in ("held", "growing", "sliding")))'
    }
    for ((r = 0; r < rounds; r++)); do
        if ((r % 2 == 0)); then
            echo "   with huge pages   : $(products "")"; echo "   without huge pages: $(products huge-pages)"
        else
            echo "   without huge pages: $(products huge-pages)"; echo "   with huge pages   : $(products "")"
        fi
    done
fi
[[ " $parts " == *" 3 "* ]] || exit 0

cargo build --release --quiet
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then
    scenes=(config/sylvian.ron config/real_brain/sylvian.ron)
fi
replay() { # OFF SCENE -> "p50 p95 solve-p95 hash"
    local out
    out=$(FISSURE_FEM_OFF="$1" ./target/release/fissure replay "$2" --out "target/fem-audit" 2>/dev/null) || { echo "replay of $2 with FISSURE_FEM_OFF=$1 failed" >&2; return 1; }
    local frame solve hash
    frame=$(grep -m1 'frame time p50' <<<"$out" | sed -E 's/.*p50 ([0-9.]+) ms, p95 ([0-9.]+) ms.*/\1 \2/')
    solve=$(grep -m1 '^ *solve ' <<<"$out" | sed -E 's/.*p95 +([0-9.]+) ms.*/\1/')
    hash=$(grep -m1 'final state' <<<"$out" | awk '{print substr($3, 1, 8)}')
    echo "$frame $solve $hash"
}
echo "== 3. scene-level switches: whole replays, $rounds rounds alternating; frame p50 / p95, solve p95 (ms), final state"
for scene in "${scenes[@]}"; do
    replay "" "$scene" >/dev/null # writes the compliance cache; not counted
    for off in ${SWITCHES:-candidate-blocks w-factor-reuse candidate-screen screen-across-frames prefetch-blocks kept-row-pairs tether-columns parallel-product}; do
        on_runs=(); off_runs=()
        for ((r = 0; r < rounds; r++)); do
            if ((r % 2 == 0)); then
                on_runs+=("$(replay "" "$scene")"); off_runs+=("$(replay "$off" "$scene")")
            else
                off_runs+=("$(replay "$off" "$scene")"); on_runs+=("$(replay "" "$scene")")
            fi
        done
        echo "$scene, $off:"
        for x in "${on_runs[@]}"; do echo "   on : $x"; done
        for x in "${off_runs[@]}"; do echo "   off: $x"; done
    done
done
