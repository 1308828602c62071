#!/usr/bin/env bash
# Runs every performance measure of fissure in one go and writes
# docs/performance.md: the machine, date, commit and command at the top, a
# summary table (one row a measure: today's figure, its goal, its command)
# between the performance-summary markers, then each measure's full section.
# The same summary is then copied into README.md between the same markers
# (tests/suite/performance_doc.rs holds the two equal).
#
#   scripts/perf_docs.sh            # every measure, about 20 minutes on 2 cores
#   FAST=1 scripts/perf_docs.sh     # one run a replay; no fem audit, no coarse-brain
#                                   # fem bench, no cold early start, no CHOLMOD: under 8 minutes
#   scripts/perf_docs.sh --readme   # only copy docs/performance.md's summary into README.md
#
# Environment: FAST=1 (above); REPEAT=N replays each scene N times (default 3,
# 1 with FAST=1; the summary gives the medians).
#
# Measures, in order (the raw output of each is kept in target/perf/, so the
# parsing can be checked against it):
#   1. `fissure bench collision --frames 30`: the collision stage per backend
#      (paper-12k and both real brains in assets/brain).
#   2. `fissure replay` of every shipped scene (config/*.ron, config/real_brain/*.ron)
#      and the fine brain's wide press, REPEAT times each, the compliance cache off.
#   3. startup (examples/startup_probe.rs): the fine brain (q15) cold and from a
#      cache, with and without --background (early start, as the window runs it),
#      and the fine-brain Sylvian scene as shipped.
#   4. the window under Xvfb on the software renderer (when Xvfb is installed).
#   5. `cargo bench --bench fem -- paper coarse` and its `audit` group.
#   6. scripts/cholmod_compare.sh, when CHOLMOD is installed.
# The real-GPU table cannot be measured here: the section between the
# gpu-table markers is copied through from the docs/performance.md already
# there; a run of scripts/gpu_devkit.sh on a GPU machine replaces it.
#
# Any measure that fails stops the script with a non-zero exit naming it;
# docs/performance.md and README.md are only replaced once every measure has
# run (each is written to a temporary file, then moved over the old one).
set -euo pipefail
cd "$(dirname "$0")/.."

DOC=docs/performance.md
SUMMARY_BEGIN='<!-- performance summary: begin -->'
SUMMARY_END='<!-- performance summary: end -->'
GPU_BEGIN='<!-- gpu table: begin -->'
GPU_END='<!-- gpu table: end -->'

log() { printf '[perf_docs %s] %s\n' "$(date -u +%H:%M:%S)" "$*" >&2; }
die() {
    printf 'perf_docs: FAILED: %s\n' "$*" >&2
    exit 1
}

# The lines of FILE strictly between the two marker lines BEGIN and END.
between_markers() {
    awk -v b="$2" -v e="$3" '$0 == e { on = 0 } on { print } $0 == b { on = 1 }' "$1"
}

# README.md's summary block becomes docs/performance.md's (temp file, then move).
copy_summary_to_readme() {
    grep -qxF "$SUMMARY_BEGIN" "$DOC" && grep -qxF "$SUMMARY_END" "$DOC" || die "$DOC has no performance summary markers"
    grep -qxF "$SUMMARY_BEGIN" README.md && grep -qxF "$SUMMARY_END" README.md || die "README.md has no performance summary markers"
    awk -v b="$SUMMARY_BEGIN" -v e="$SUMMARY_END" -v src="$DOC" '
        BEGIN { while ((getline line < src) > 0) { if (line == e) on = 0; if (on) summary = summary line "\n"; if (line == b) on = 1 } }
        $0 == b { print; printf "%s", summary; skip = 1; next }
        $0 == e { skip = 0 }
        !skip { print }
    ' README.md > README.md.perf-tmp
    mv README.md.perf-tmp README.md
    log "README.md's performance summary copied from $DOC"
}

case "${1:-}" in
    --readme)
        copy_summary_to_readme
        exit 0
        ;;
    "") ;;
    -h | --help)
        sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'
        exit 0
        ;;
    *)
        echo "usage: scripts/perf_docs.sh [--readme]   (FAST=1, REPEAT=N in the environment)" >&2
        exit 2
        ;;
esac

FAST="${FAST:-0}"
[ "$FAST" = 1 ] && default_repeat=1 || default_repeat=3
REPEAT="${REPEAT:-$default_repeat}"
PERF=target/perf
FISSURE=target/release/fissure
PROBE=target/release/examples/startup_probe
Q15_MESH='mesh=File(path: "../../assets/brain/brain_pial_q15.msh.gz", units: Millimetres)'
NOT_RUN_FAST='not run (FAST=1)'

# ---------------------------------------------------------------- functions

# Numbers on stdin, one a line: the median (the middle one; the mean of the two middle ones).
median() {
    sort -g | awk '{ a[NR] = $1 } END { if (NR == 0) print "n/a"; else if (NR % 2) print a[(NR + 1) / 2]; else printf "%.3f\n", (a[NR / 2] + a[NR / 2 + 1]) / 2 }'
}
# Numbers on stdin: "min-max" (one value when they are equal).
range() {
    sort -g | awk 'NR == 1 { lo = $1 } { hi = $1 } END { if (NR == 0) print "n/a"; else if (lo == hi) print lo; else print lo "-" hi }'
}
maximum() { sort -g | tail -1; }
# "met" when VALUE < LIMIT, "not met" otherwise, "not measured" without a value.
verdict() {
    case "${1:-}" in '' | n/a | NaN | nan | inf) echo "not measured"; return ;; esac
    awk -v v="$1" -v l="$2" 'BEGIN { print (v + 0 < l + 0) ? "met" : "not met" }'
}
# "met" when VALUE <= LIMIT.
at_most() {
    case "${1:-}" in '' | n/a | NaN | nan | inf) echo "not measured"; return ;; esac
    awk -v v="$1" -v l="$2" 'BEGIN { print (v + 0 <= l + 0) ? "met" : "not met" }'
}
# A / B with two decimals ("n/a" when either is missing).
ratio() {
    awk -v a="${1:-}" -v b="${2:-}" 'BEGIN { if (a == "" || b == "" || a == "n/a" || b == "n/a" || b + 0 == 0) print "n/a"; else printf "%.2f\n", a / b }'
}
fmt() { awk -v v="${2:-}" -v f="$1" 'BEGIN { if (v == "" || v == "n/a") print "n/a"; else printf f "\n", v }'; }
# The first capture of sed regex RE (basic syntax, one group) in FILE.
grab() { sed -n "s/$2/\1/p" "$1" | head -1; }

# Runs a measure's command; stdout and stderr go to LOG; a failure stops the
# script naming the measure and showing the end of its output.
run_measure() {
    local name=$1 logfile=$2
    shift 2
    log "$name: $*"
    if ! "$@" > "$logfile" 2>&1; then
        tail -n 25 "$logfile" >&2 || true
        die "$name (command: $*; output: $logfile)"
    fi
}
# The same under /usr/bin/time when it is installed: "wall_s peak_kb" in TIMEFILE.
run_timed() {
    local name=$1 logfile=$2 timefile=$3
    shift 3
    if [ -x /usr/bin/time ]; then
        run_measure "$name" "$logfile" /usr/bin/time -f '%e %M' -o "$timefile" "$@"
    else
        local start=$SECONDS
        run_measure "$name" "$logfile" "$@"
        echo "$((SECONDS - start)) n/a" > "$timefile"
    fi
}

xvfb_pid=""
XDG_TMP=""
cleanup() {
    if [ -n "$xvfb_pid" ]; then kill "$xvfb_pid" 2> /dev/null || true; fi
    if [ -n "$XDG_TMP" ]; then rm -rf "$XDG_TMP"; fi
    rm -f README.md.perf-tmp
}
trap cleanup EXIT

# ---------------------------------------------------------------- start

t_script=$SECONDS
rm -rf "$PERF"
mkdir -p "$PERF"
# The real-GPU section as it is now, carried through untouched.
if [ -f "$DOC" ] && grep -qxF "$GPU_BEGIN" "$DOC" && grep -qxF "$GPU_END" "$DOC"; then
    { echo "$GPU_BEGIN"; between_markers "$DOC" "$GPU_BEGIN" "$GPU_END"; echo "$GPU_END"; } > "$PERF/gpu_section.md"
else
    printf '%s\n\nNot measured yet: run `bash scripts/gpu_devkit.sh`, then `REPLAY=1 SYLVIAN=1 bash .devkit/run.sh` on a machine with a GPU, and put its table here with that machine, date and commit.\n\n%s\n' \
        "$GPU_BEGIN" "$GPU_END" > "$PERF/gpu_section.md"
fi

# What the header says, taken before anything is built.
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)
cores=$(nproc)
ram=$(awk '/^MemTotal:/ { printf "%.1f GiB", $2 / 1048576 }' /proc/meminfo)
date_utc=$(date -u '+%Y-%m-%d %H:%M UTC')
commit=$(git rev-parse --short HEAD)
# Tracked changes, leaving out the files this script itself writes.
if [ -n "$(git status --porcelain --untracked-files=no -- . ':(exclude)docs/performance.md' ':(exclude)README.md' ':(exclude)docs/images/fem_*.png')" ]; then
    commit="$commit + uncommitted changes"
fi
command_line="scripts/perf_docs.sh"
[ "$FAST" = 1 ] && command_line="FAST=1 $command_line"
[ "$REPEAT" != "$default_repeat" ] && command_line="REPEAT=$REPEAT $command_line"

# The software Vulkan driver for the `gpu` rows and the window, as scripts/test.sh sets it.
scripts/deps.sh || die "scripts/deps.sh (the system packages)"
if [ -z "${VK_DRIVER_FILES:-}" ] && [ -f /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ]; then
    export VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
    export WGPU_BACKEND="${WGPU_BACKEND:-vulkan}"
fi
XDG_TMP=$(mktemp -d)
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$XDG_TMP}"
export RUST_LOG="${RUST_LOG:-error,fissure=warn}"

log "building (release: binaries, examples, the fem bench)"
run_measure "build" "$PERF/build.log" cargo build --release --examples --bins
run_measure "build (fem bench)" "$PERF/build_bench.log" cargo bench --bench fem --no-run

# ---------------------------------------------------------------- 1. collision bench

t0=$SECONDS
run_measure "collision bench" "$PERF/collision.log" "$FISSURE" bench collision --frames 30 --out "$PERF/collision.md" --json "$PERF/collision.json"
if grep -q 'cases are skipped' "$PERF/collision.log"; then
    die "collision bench: a real brain was not found ($(grep 'cases are skipped' "$PERF/collision.log" | head -1))"
fi
# A row's field, from the JSON the bench wrote (src/cli/bench.rs's CollisionReport): bench_cell SURFACE NODES
# BACKEND FIELD; a missing row or field says so and prints nothing.
bench_cell() {
    python3 - "$PERF/collision.json" "$@" <<'PY'
import json, sys
path, surface, nodes, backend, field = sys.argv[1:]
try:
    rows = [r for r in json.load(open(path))["rows"] if (r["surface"], r["nodes_a_face"], r["backend"]) == (surface, int(nodes), backend)]
    print(f"{rows[0][field]:.3f}")
except (OSError, ValueError, KeyError, IndexError) as e:
    print(f"{path}: no {field} of {surface} {nodes} {backend}: {type(e).__name__}: {e}", file=sys.stderr)
    sys.exit(1)
PY
}
coll_bvh_p50=$(bench_cell paper-12k 500 bvh p50_ms)
coll_bvh_p95=$(bench_cell paper-12k 500 bvh p95_ms)
coll_gpu_p50=$(bench_cell paper-12k 500 gpu p50_ms)
coll_gpu_p95=$(bench_cell paper-12k 500 gpu p95_ms)
coll_q15_p50=$(bench_cell brain-q15 500 bvh p50_ms)
coll_q15_p95=$(bench_cell brain-q15 500 bvh p95_ms)
[ -n "$coll_bvh_p50" ] && [ -n "$coll_q15_p95" ] || die "collision bench: no paper-12k or brain-q15 500 bvh row in $PERF/collision.json"
gpu_adapter=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["device"])' "$PERF/collision.json") ||
    die "collision bench: no device in $PERF/collision.json"
t_collision=$((SECONDS - t0))

# ---------------------------------------------------------------- 2. replays

t0=$SECONDS
mkdir -p "$PERF/replay"
# One line a run in replays.tsv: tag, run, frames, p50, p95, max, stages,
# wall s, peak MB, contact vertices at the end, forces at the end (N), integrity, final state.
: > "$PERF/replays.tsv"
parse_replay() {
    local tag=$1 k=$2 base=$3
    local frames p50 p95 max stages hash integrity wall peak_kb peak cv forces substeps jumps
    # The figures as the replay wrote them in summary.json (src/sim/report.rs's types), not as it printed them: a
    # missing field stops the run naming it.
    IFS=$'\t' read -r frames p50 p95 max stages hash integrity substeps jumps < <(python3 - "$base/summary.json" <<'PY'
import json, sys
try:
    d = json.load(open(sys.argv[1]))
    f = d["frame"]
    stages = "; ".join(f"{name} {s['p50_ms']:.3f} / {s['p95_ms']:.3f}" for name, s in d["stages"])
    jumps = "/".join(f"{s['p95_force_jump_n']:.4f}" for s in d["spatulas"]) or "-"
    print("\t".join(str(x) for x in (d["frames"], f"{f['p50_ms']:.3f}", f"{f['p95_ms']:.3f}", f"{f['max_ms']:.3f}", stages,
                                      d["final_state_hash"], "pass" if d["integrity"]["passed"] else "FAIL", d["max_substeps"], jumps)))
except (OSError, ValueError, KeyError, TypeError) as e:
    print(f"{sys.argv[1]}: {type(e).__name__}: {e}", file=sys.stderr)
    sys.exit(1)
PY
) || true
    [ -n "${p95:-}" ] && [ -n "${hash:-}" ] || die "replay $tag: could not read its figures from $base/summary.json"
    read -r wall peak_kb < <(tail -n 1 "$base.time") || true
    peak=$(awk -v k="$peak_kb" 'BEGIN { if (k == "n/a" || k == "") print "n/a"; else printf "%.0f\n", k / 1024 }')
    read -r cv forces < <(awk -F, '
        NR == 1 { for (i = 1; i <= NF; i++) { if ($i ~ /_contact_vertices$/) c[++n] = i; if ($i ~ /_force_n$/) f[++m] = i }; next }
        { last = $0 }
        END {
            split(last, v, ",")
            s = ""; for (j = 1; j <= n; j++) s = s (j > 1 ? "/" : "") v[c[j]]
            t = ""; for (j = 1; j <= m; j++) t = t (j > 1 ? "/" : "") sprintf("%.3f", v[f[j]])
            print (s == "" ? "-" : s), (t == "" ? "-" : t)
        }' "$base/metrics.csv") || true
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' \
        "$tag" "$k" "$frames" "$p50" "$p95" "$max" "$stages" "$wall" "$peak" "$cv" "$forces" "$integrity" "$hash" "${substeps:-1}" "${jumps:--}" >> "$PERF/replays.tsv"
}
# replay_once TAG K SCENARIO [ARGS..]: run K of one scene (the first run names the tag).
declare -A replay_cmd
replay_tags=()
replay_once() {
    local tag=$1 k=$2 scenario=$3
    shift 3
    if [ -z "${replay_cmd[$tag]:-}" ]; then
        replay_tags+=("$tag")
        replay_cmd[$tag]="fissure replay $scenario --set solver.cache_dir=None${*:+ $*}"
    fi
    local base="$PERF/replay/${tag//\//_}_$k"
    rm -rf "$base"
    run_timed "replay $tag (run $k of $REPEAT)" "$base.log" "$base.time" \
        "$FISSURE" replay "$scenario" --set solver.cache_dir=None "$@" --out "$base"
    parse_replay "$tag" "$k" "$base"
}
# replay TAG SCENARIO [ARGS..]: REPEAT runs of one scene.
replay() {
    local tag=$1 scenario=$2
    shift 2
    local k
    for k in $(seq 1 "$REPEAT"); do
        replay_once "$tag" "$k" "$scenario" "$@"
    done
}
# Every shipped scene with a trajectory (config/study_fissure.ron has none: the
# study moves its blade itself), the default scene first.
for scenario in config/sylvian.ron $(grep -l 'trajectory: Some(' config/*.ron | grep -vx config/sylvian.ron) $(grep -l 'trajectory: Some(' config/real_brain/*.ron); do
    tag=${scenario#config/}
    tag=${tag%.ron}
    replay "$tag" "$scenario"
done
replay real_brain/sylvian_wide config/real_brain/sylvian.ron --trajectory assets/trajectories/real_brain_sylvian_wide.csv --set duration_s=4.5
# The default scene's spread as a jittery tracker sends it (+-0.5 mm on each
# coordinate every 10 ms, scripts/noisy_track.py), the poses as they come and
# through the One Euro filter a tracker binding gets by default.
one_euro='OneEuro(min_cutoff_hz: 1.0, beta_hz_per_mm_s: 0.05, d_cutoff_hz: 1.0)'
replay sylvian_noisy config/sylvian.ron --trajectory assets/trajectories/paper_fig14_sylvian_noisy.csv
replay sylvian_noisy_filtered config/sylvian.ron --trajectory assets/trajectories/paper_fig14_sylvian_noisy.csv \
    --set "spatulas[0].filter=$one_euro" --set "spatulas[1].filter=$one_euro"
# The same blade motion on the coarse and the fine brain: the fine-brain Sylvian
# scene as a user writes it (no `refine`, so `Auto`; the lowest 10 mm held), on each brain, with the working
# region's rows (the default) and with a row for every surface vertex.
coarse_mesh='mesh=File(path: "../../assets/brain/brain_pial_coarse.msh.gz", units: Millimetres)'
user_scene=(--set "fixed=[LowestPerComponent(height_mm: 10.0)]")
replay size/coarse config/real_brain/sylvian.ron "${user_scene[@]}" --set "$coarse_mesh"
replay size/coarse_all config/real_brain/sylvian.ron "${user_scene[@]}" --set "$coarse_mesh" --set solver.row_band_mm=None
replay size/fine config/real_brain/sylvian.ron "${user_scene[@]}"
replay size/fine_all config/real_brain/sylvian.ron "${user_scene[@]}" --set solver.row_band_mm=None
# What the effects cost on the fine-brain Sylvian opening: without any, as shipped (relaxation and
# ischemia), and with its vessels and arachnoid bands (config/real_brain/sylvian_tethers.ron, the same
# scene and motion), alternating run by run so that the ratios are measured under the same load.
plain_effects='effects=[Collision, Culling, ForceOutput, ContactPressure]'
for k in $(seq 1 "$REPEAT"); do
    replay_once effects/none "$k" config/real_brain/sylvian.ron --set "$plain_effects"
    replay_once effects/tissue "$k" config/real_brain/sylvian.ron
    replay_once effects/tethers "$k" config/real_brain/sylvian_tethers.ron
done
# The same scene opened roughly (no cut, wider, faster): many bands taut at once, then torn (one run).
replay_once effects/tethers_rough 1 config/real_brain/sylvian_tethers.ron --trajectory assets/trajectories/real_brain_sylvian_rough.csv
# Ten minutes held: continuously, and with a minute's rest halfway (one run each).
replay_once hold/continuous 1 config/real_brain/sylvian.ron --trajectory assets/trajectories/real_brain_sylvian_hold.csv --set duration_s=603.5
replay_once hold/intermittent 1 config/real_brain/sylvian.ron --trajectory assets/trajectories/real_brain_sylvian_intermittent.csv --set duration_s=668
# A field of a run's summary.json (its first run): hold_field TAG PYTHON_EXPRESSION_OF_s.
hold_field() {
    python3 -c 'import json, sys; s = json.load(open(sys.argv[1])); print(eval(sys.argv[2]))' "$PERF/replay/${1//\//_}_1/summary.json" "$2" ||
        die "replay $1: no such field in its summary.json: $2"
}
# The rows, surface vertices and columns a size/ run's compliance has.
size_rows() { hold_field "size/$1" 's["compliance"]["rows"]'; }
size_surface() { hold_field "size/$1" 's["compliance"]["surface_vertices"]'; }
size_cols() { hold_field "size/$1" 's["compliance"]["columns"]'; }
# Per tag: the medians of p50 and p95 over the runs, the largest max, the p95 range.
replay_stat() { # TAG COLUMN (1-based in replays.tsv) -> that column of every run, one a line
    awk -F'\t' -v t="$1" -v c="$2" '$1 == t { print $c }' "$PERF/replays.tsv"
}
replay_p50() { replay_stat "$1" 4 | median; }
replay_p95() { replay_stat "$1" 5 | median; }
replay_max() { replay_stat "$1" 6 | maximum; }
replay_p95_range() { replay_stat "$1" 5 | range; }
replay_last() { replay_stat "$1" "$2" | tail -1; }
t_replays=$((SECONDS - t0))

# ---------------------------------------------------------------- 3. startup

t0=$SECONDS
mkdir -p "$PERF/startup"
q15_cache="$PERF/startup/cache_q15"
sylvian_cache="$PERF/startup/cache_sylvian"
rm -rf "$q15_cache" "$sylvian_cache"
probe_q15=("$PROBE" config/real_brain/interhemispheric.ron "$Q15_MESH" solver.compliance_storage=F32)
# A. Cold, the build that computes every column first; it writes the cache the next runs read.
run_measure "startup: fine brain cold" "$PERF/startup/q15_cold.log" "${probe_q15[@]}" "solver.cache_dir=Some(\"$q15_cache\")" --json "$PERF/startup/q15_cold.json"
# B. Cold with early start, as the window runs it (no cache).
if [ "$FAST" != 1 ]; then
    run_measure "startup: fine brain cold, early start" "$PERF/startup/q15_cold_background.log" "${probe_q15[@]}" solver.cache_dir=None --background --json "$PERF/startup/q15_cold_background.json"
fi
# C, D. From the cache, without and with early start.
run_measure "startup: fine brain from the cache" "$PERF/startup/q15_cache.log" "${probe_q15[@]}" "solver.cache_dir=Some(\"$q15_cache\")" --json "$PERF/startup/q15_cache.json"
run_measure "startup: fine brain from the cache, early start" "$PERF/startup/q15_cache_background.log" "${probe_q15[@]}" "solver.cache_dir=Some(\"$q15_cache\")" --background --json "$PERF/startup/q15_cache_background.json"
# E, F. The fine-brain Sylvian scene as shipped: cold (writes its cache), then from the cache with early start.
run_measure "startup: fine-brain Sylvian scene cold" "$PERF/startup/sylvian_cold.log" "$PROBE" config/real_brain/sylvian.ron "solver.cache_dir=Some(\"$sylvian_cache\")" --json "$PERF/startup/sylvian_cold.json"
run_measure "startup: fine-brain Sylvian scene from the cache, early start" "$PERF/startup/sylvian_cache_background.log" "$PROBE" config/real_brain/sylvian.ron "solver.cache_dir=Some(\"$sylvian_cache\")" --background --json "$PERF/startup/sylvian_cache_background.json"
# G. The same scene as a user writes it: no `refine` (so `Auto`), only the lowest 10 mm held, f64, no cache.
user_sylvian=("fixed=[LowestPerComponent(height_mm: 10.0)]" solver.compliance_storage=F64 solver.cache_dir=None solver.early_start=false)
run_measure "startup: a user's fine-brain Sylvian scene cold" "$PERF/startup/user_sylvian_cold.log" "$PROBE" config/real_brain/sylvian.ron "${user_sylvian[@]}" --json "$PERF/startup/user_sylvian_cold.json"
# H. The same opened as the window opens it (early start): the frames that wait for their columns.
run_measure "startup: a user's fine-brain Sylvian scene cold, early start" "$PERF/startup/user_sylvian_background.log" "$PROBE" config/real_brain/sylvian.ron "${user_sylvian[@]}" solver.early_start=true --background --json "$PERF/startup/user_sylvian_background.json"

# Fields of a JSON report (examples/startup_probe.rs's StartupReport, `fissure run --report`'s, the fem bench's
# FemFigures), tab-separated in the order asked, each `path.to.field` (a number indexes a list) or
# `path.to.field:FORMAT` (a Python format spec); a field that is missing stops the run naming it, one that is
# null (not a number) reads n/a.
json_fields() {
    python3 - "$@" <<'PY'
import json, sys
path, fields = sys.argv[1], sys.argv[2:]
try:
    d = json.load(open(path))
    out = []
    for f in fields:
        name, _, spec = f.partition(":")
        v = d
        for k in name.split("."):
            v = v[int(k)] if isinstance(v, list) else v[k]
        text = "n/a" if v is None else str(v).lower() if isinstance(v, bool) else format(v, spec)
        if spec.endswith("e") and v is not None:
            # As Rust writes it: 1.23e-5, not 1.23e-05.
            mantissa, _, exponent = text.partition("e")
            text = f"{mantissa}e{int(exponent)}"
        out.append(text)
    print("\t".join(out))
except (OSError, ValueError, KeyError, TypeError) as e:
    print(f"{path}: {type(e).__name__}: {e}", file=sys.stderr)
    sys.exit(1)
PY
}
# Figures of a build that waits for every column: model + factor (s before the
# compliance), compliance compute / load s, whole build s, peak MB, from cache, rows, cols, MB.
probe_build() {
    local f=$1
    build=
    IFS=$'\t' read -r before build peak compute load from_cache rows cols mb < <(json_fields "$f" \
        build.before_compliance_s:.2f build.build_s:.2f build.peak_rss_mb:.0f build.compliance.compute_s:.2f \
        build.compliance.load_s:.2f build.compliance.from_cache build.compliance.rows build.compliance.cols \
        build.compliance.megabytes:.0f) || true
    [ -n "$build" ] || die "startup: no build figures in $f"
}
# Figures of an early start: first frame s, frames, motion done s, slowest ms,
# frames over 50 ms, every column final s, peak MB.
probe_background() {
    local f=$1
    first=
    IFS=$'\t' read -r first frames_n motion slowest over50 columns bpeak < <(json_fields "$f" \
        early_start.first_frame_s:.2f early_start.frames early_start.motion_done_s:.2f early_start.slowest_frame_ms:.0f \
        early_start.frames_over_50ms early_start.columns_final_s:.2f early_start.peak_rss_mb:.0f) || true
    [ -n "$first" ] || die "startup: no early-start figures in $f"
}
probe_build "$PERF/startup/q15_cold.json"
[ "$from_cache" = false ] || die "startup: the cold run read a cache ($PERF/startup/q15_cold.json)"
cold_before=$before cold_build=$build cold_peak=$peak cold_compute=$compute cold_rows=$rows cold_cols=$cols cold_mb=$mb
probe_build "$PERF/startup/q15_cache.json"
[ "$from_cache" = true ] || die "startup: the second run did not read the cache the first wrote ($PERF/startup/q15_cache.json)"
cache_build=$build cache_load=$load cache_peak=$peak
probe_build "$PERF/startup/sylvian_cold.json"
syl_cold_build=$build syl_rows=$rows syl_cols=$cols syl_mb=$mb syl_cold_peak=$peak
probe_build "$PERF/startup/user_sylvian_cold.json"
usr_before=$before usr_compute=$compute usr_build=$build usr_peak=$peak usr_rows=$rows usr_cols=$cols usr_mb=$mb
if [ "$FAST" != 1 ]; then
    probe_background "$PERF/startup/q15_cold_background.json"
    bgc_first=$first bgc_motion=$motion bgc_slowest=$slowest bgc_over50=$over50 bgc_columns=$columns bgc_peak=$bpeak bgc_frames=$frames_n
fi
probe_background "$PERF/startup/q15_cache_background.json"
bgk_first=$first bgk_motion=$motion bgk_slowest=$slowest bgk_over50=$over50 bgk_columns=$columns bgk_peak=$bpeak bgk_frames=$frames_n
probe_background "$PERF/startup/sylvian_cache_background.json"
syl_first=$first syl_slowest=$slowest syl_over50=$over50 syl_columns=$columns syl_peak=$bpeak
probe_background "$PERF/startup/user_sylvian_background.json"
usb_first=$first usb_motion=$motion usb_slowest=$slowest usb_over50=$over50 usb_columns=$columns usb_peak=$bpeak usb_frames=$frames_n
t_startup=$((SECONDS - t0))

# ---------------------------------------------------------------- 4. the window

t0=$SECONDS
window_status="not run: Xvfb is not installed (scripts/deps.sh installs it)"
if command -v Xvfb > /dev/null 2>&1; then
    for n in $(seq 90 140); do
        [ -e "/tmp/.X11-unix/X$n" ] || [ -e "/tmp/.X$n-lock" ] && continue
        Xvfb ":$n" -screen 0 1920x1080x24 -nolisten tcp > /dev/null 2>&1 &
        xvfb_pid=$!
        for _ in $(seq 100); do [ -e "/tmp/.X11-unix/X$n" ] && break; sleep 0.1; done
        if [ -e "/tmp/.X11-unix/X$n" ]; then
            display=":$n"
            break
        fi
        kill "$xvfb_pid" 2> /dev/null || true
        xvfb_pid=""
    done
    [ -n "$xvfb_pid" ] || die "window: Xvfb did not start"
    mkdir -p "$PERF/window"
    window_cache="$PERF/window/cache"
    window_args=(run config/sylvian.ron --size 1280x800 --set "solver.cache_dir=Some(\"$window_cache\")")
    # The first run fills the compliance cache in the background (not
    # counted; 20 s leave the columns time to finish and be written); then
    # llvmpipe on cores - 1 threads (what `fissure run` sets) and on every core.
    run_measure "window: warm-up" "$PERF/window/warmup.log" env DISPLAY="$display" timeout 180 "$FISSURE" "${window_args[@]}" --exit-after 20
    window_args+=(--exit-after 10)
    run_measure "window: llvmpipe on cores - 1 threads" "$PERF/window/threads_default.log" env -u LP_NUM_THREADS DISPLAY="$display" timeout 180 "$FISSURE" "${window_args[@]}" --report "$PERF/window/threads_default.json"
    run_measure "window: llvmpipe on every core" "$PERF/window/threads_all.log" env LP_NUM_THREADS="$cores" DISPLAY="$display" timeout 180 "$FISSURE" "${window_args[@]}" --report "$PERF/window/threads_all.json"
    kill "$xvfb_pid" 2> /dev/null || true
    xvfb_pid=""
    for f in "$PERF/window/threads_default.log" "$PERF/window/threads_all.log"; do
        grep -q '^window: ' "$f" || die "window: no 'window:' line in $f (did it fall back to headless?)"
    done
    window_status=ran
fi
# window_figures FILE: fps, step p50 and p95 (ms) and the adapter, from the JSON `fissure run --report` wrote.
window_figures() {
    local f=$1
    wfps=
    IFS=$'\t' read -r wfps wp50 wp95 wadapter < <(json_fields "$f" fps:.1f step_p50_ms:.3f step_p95_ms:.3f adapter) || true
    [ -n "$wfps" ] || die "window: no figures in $f"
}
t_window=$((SECONDS - t0))

# ---------------------------------------------------------------- 5. fem bench

t0=$SECONDS
fem_models=(paper coarse)
fem_models_json=(paper-12k brain_pial_coarse)
[ "$FAST" = 1 ] && fem_models=(paper) && fem_models_json=(paper-12k)
rm -rf target/fem-bench-cache/figures
run_measure "fem bench" "$PERF/fem.log" cargo bench --quiet --bench fem -- "${fem_models[@]}"
cp -f target/fem-bench-cache/sweep/paper-12k_constrained_sweep.png "$PERF/fem_constrained_sweep.png" 2> /dev/null || true
if [ "$FAST" != 1 ]; then
    run_measure "fem bench audit" "$PERF/fem_audit.log" cargo bench --quiet --bench fem -- audit "${fem_models[@]}"
    cp -f target/fem-bench-cache/audit/paper-12k_audit.png "$PERF/fem_audit_paper12k.png" 2> /dev/null || true
    cp -f target/fem-bench-cache/audit/brain_pial_coarse_audit.png "$PERF/fem_audit_coarse_brain.png" 2> /dev/null || true
fi
# fem_figures MODEL: sets f_* from the figures the fem bench wrote for that model (benches/fem.rs's FemFigures).
fem_figures() {
    local j="target/fem-bench-cache/figures/$1.json"
    f_pre=
    IFS=$'\t' read -r f_nodes f_factor f_amd f_amd_exact f_nd f_nd_exact f_nd_solve f_rows f_cols f_mb f_pre f_reload f_peak \
        < <(json_fields "$j" nodes factor_total_s:.3f orderings.0.nnz_l_millions:.2f orderings.0.exact_nnz_l_millions:.2f \
            orderings.1.nnz_l_millions:.2f orderings.1.exact_nnz_l_millions:.2f orderings.1.solve_over_amd:.2f \
            compliance.rows compliance.cols compliance.megabytes:.0f compliance.precompute_s:.2f compliance.reload_s:.3f \
            peak_rss_mb:.0f) || true
    [ -n "$f_pre" ] || die "fem bench: no figures for $1 in $j"
    f_p95_300=
    # The frames at 100 and at 300 constrained; the floors at 300.
    IFS=$'\t' read -r f_p50_100 f_p95_100 f_p50_300 f_p95_300 f_floor_x f_floor f_two_x f_two f_product f_product_floor f_stream \
        f_err_u f_err_r < <(json_fields "$j" frames.0.p50_ms:.2f frames.0.p95_ms:.2f frames.1.p50_ms:.2f frames.1.p95_ms:.2f \
            frames.1.p95_over_floor:.1f frames.1.floor_ms:.2f frames.1.p95_over_two_floors:.1f frames.1.two_floors_ms:.2f \
            frames.1.product_ms:.2f frames.1.product_floor_ms:.2f frames.1.stream_gb_s:.1f error_vs_f64.displacement:.2e \
            error_vs_f64.reaction:.2e) || true
    [ -n "$f_p95_300" ] || die "fem bench: no frame figures for $1 in $j"
}
# "SWITCH GAIN" a line, in the audit's order, from the JSON the fem bench's audit wrote for each model
# (benches/fem.rs's AuditBar: the phase it touches, off / on, two decimals).
audit_gains() {
    local m
    for m in "${fem_models_json[@]}"; do
        python3 - "target/fem-bench-cache/figures/${m}_audit.json" <<'PY' || die "fem bench audit: no figures in target/fem-bench-cache/figures/${m}_audit.json"
import json, sys
for bar in json.load(open(sys.argv[1])):
    print(bar["switch"], f"{bar['off'] / bar['on']:.2f}")
PY
    done
}
fem_figures paper-12k
p_factor=$f_factor p_amd=$f_amd p_amd_exact=$f_amd_exact p_nd=$f_nd p_nd_exact=$f_nd_exact p_nd_solve=$f_nd_solve
p_rows=$f_rows p_cols=$f_cols p_mb=$f_mb p_pre=$f_pre p_reload=$f_reload p_peak=$f_peak
p_p50_100=$f_p50_100 p_p95_100=$f_p95_100 p_p50_300=$f_p50_300 p_p95_300=$f_p95_300
p_floor_x=$f_floor_x p_floor=$f_floor p_two_x=$f_two_x p_two=$f_two p_product=$f_product p_product_floor=$f_product_floor p_stream=$f_stream
p_err_u=$f_err_u p_err_r=$f_err_r p_nodes=$f_nodes
if [ "$FAST" != 1 ]; then
    fem_figures brain_pial_coarse
    c_factor=$f_factor c_amd=$f_amd c_amd_exact=$f_amd_exact c_nd=$f_nd c_nd_exact=$f_nd_exact c_nd_solve=$f_nd_solve
    c_rows=$f_rows c_cols=$f_cols c_mb=$f_mb c_pre=$f_pre c_reload=$f_reload c_peak=$f_peak
    c_p50_100=$f_p50_100 c_p95_100=$f_p95_100 c_p50_300=$f_p50_300 c_p95_300=$f_p95_300
    c_floor_x=$f_floor_x c_floor=$f_floor c_two_x=$f_two_x c_two=$f_two c_product=$f_product c_product_floor=$f_product_floor c_stream=$f_stream
    c_err_u=$f_err_u c_err_r=$f_err_r c_nodes=$f_nodes
    for m in "${fem_models_json[@]}"; do
        [ -s "target/fem-bench-cache/figures/${m}_audit.json" ] || die "fem bench audit: no target/fem-bench-cache/figures/${m}_audit.json"
    done
fi
t_fem=$((SECONDS - t0))

# ---------------------------------------------------------------- 6. CHOLMOD

t0=$SECONDS
cholmod_status="not run: CHOLMOD is not installed (apt-get install libsuitesparse-dev libopenblas0-pthread, then run this script again)"
if [ "$FAST" = 1 ]; then
    cholmod_status="$NOT_RUN_FAST"
elif [ -f /usr/include/suitesparse/cholmod.h ]; then
    run_measure "CHOLMOD comparison" "$PERF/cholmod.log" bash scripts/cholmod_compare.sh
    cholmod_status=ran
fi
# The median over rounds of ours / CHOLMOD's for one mesh and one ordering:
# cholmod_ratio MESH ORDERING FIELD, FIELD = exact | numeric | solve.
cholmod_ratio() {
    awk -v mesh="$1" -v ord="$2" -v field="$3" '
        /^== / { on = ($2 == mesh) }
        on && ($1 == "fissure" || $1 == "cholmod") && $2 == ord ":" {
            v = ""
            if (field == "exact" && match($0, /nnz\(L\) exact [0-9.]+/)) v = substr($0, RSTART + 14, RLENGTH - 14)
            if (field == "numeric" && match($0, /numeric [0-9.]+/)) v = substr($0, RSTART + 8, RLENGTH - 8)
            if (field == "solve" && match($0, /solve [0-9.]+/)) v = substr($0, RSTART + 6, RLENGTH - 6)
            if ($1 == "fissure") ours = v; else if (ours != "") { printf "%.3f\n", ours / v; ours = "" }
        }' "$PERF/cholmod.log" | median
}
t_cholmod=$((SECONDS - t0))

# ---------------------------------------------------------------- the summary

rp() { # TAG -> "p50 X / p95 Y ms (max M ms)": the medians over the runs, the largest max
    printf 'p50 %s / p95 %s ms (max %s ms)' "$(replay_p50 "$1")" "$(replay_p95 "$1")" "$(replay_max "$1")"
}
runs_note() { [ "$REPEAT" = 1 ] && echo "one run" || echo "median of $REPEAT runs"; }
code() { printf '`%s`' "$*"; }

summary_rows() {
    echo "| measure | today | goal | command |"
    echo "|---|---|---|---|"
    local v
    echo "| collision stage, two blades at 500 source nodes a face, paper-12k (14,810 triangles), bvh on 2 threads | p50 $coll_bvh_p50 / p95 $coll_bvh_p95 ms | under 1 ms, refit included: $(verdict "$coll_bvh_p50" 1) (p50) | $(code fissure bench collision --frames 30) |"
    if [ -n "$coll_gpu_p50" ]; then
        v=$(ratio "$coll_gpu_p50" "$coll_bvh_p50")
        echo "| the same on the gpu backend, on $gpu_adapter | p50 $coll_gpu_p50 / p95 $coll_gpu_p95 ms, ${v}x bvh | within 10x of bvh on a software driver: $(verdict "$v" 10) | the same |"
    else
        echo "| the same on the gpu backend | not run: no GPU adapter (not even a software one) | within 10x of bvh on a software driver | the same |"
    fi
    echo "| collision stage, fine real brain (q15, 67,708 triangles), 500 source nodes a face, bvh | p50 ${coll_q15_p50:-n/a} / p95 ${coll_q15_p95:-n/a} ms | under 1 ms: $(verdict "$coll_q15_p50" 1) (p50) | the same |"
    local tag p95 goal
    for tag in "${replay_tags[@]}"; do
        [[ $tag == size/* || $tag == effects/* || $tag == hold/* || $tag == real_brain/*_tethers ]] && continue
        p95=$(replay_p95 "$tag")
        case $tag in
            sylvian) goal="p95 < 2 ms (paper-size model): $(verdict "$p95" 2); < 5 ms: $(verdict "$p95" 5)" ;;
            real_brain/interhemispheric) goal="p95 < 16 ms: $(verdict "$p95" 16)" ;;
            real_brain/sylvian) goal="p95 < 4 ms (fine brain): $(verdict "$p95" 4); < 16 ms: $(verdict "$p95" 16)" ;;
            sylvian_noisy) goal="(for comparison)" ;;
            sylvian_noisy_filtered)
                v=$(ratio "$p95" "$(replay_p95 sylvian)")
                goal="p95 within 2.5x the clean spread's (default scene): ${v}x, $(verdict "$v" 2.5)"
                ;;
            real_brain/sylvian_wide)
                local cv min_cv
                cv=$(replay_last "$tag" 10)
                min_cv=$(echo "$cv" | tr '/' '\n' | sort -g | head -1)
                if [ "$(verdict "$p95" 8)" = met ] && [ "${min_cv:-0}" -ge 50 ]; then v=met; else v="not met"; fi
                goal="p95 < 8 ms with >= 50 contact vertices a blade: $v"
                ;;
            *) goal="p95 < 2 ms: $(verdict "$p95" 2)" ;;
        esac
        local what
        case $tag in
            sylvian) what="default scene: paper-12k, two spatulas, skull spheres" ;;
            interhemispheric) what="paper-9k, one spatula in the inter-hemispheric fissure" ;;
            u_shape) what="the paper's U block" ;;
            v_valley) what="the paper's V valley" ;;
            real_brain/interhemispheric) what="coarse real brain (25,757 nodes), two blades down the inter-hemispheric fissure" ;;
            real_brain/sylvian) what="fine real brain (q15), the Sylvian opening, refined where the blades reach (refine: Auto)" ;;
            real_brain/sylvian_wide) what="the same, pressed wider (the wide-press trajectory)" ;;
            sylvian_tethers) what="the default scene with its vessels and arachnoid bands, the careful opening (bands cut, then spread)" ;;
            sylvian_noisy) what="default scene, its spread with +-0.5 mm tracker noise every 10 ms, unfiltered" ;;
            sylvian_noisy_filtered) what="the same noisy spread through the One Euro filter" ;;
            *) what="$tag" ;;
        esac
        local extra=""
        case $tag in
            real_brain/sylvian) extra="; whole run $(replay_stat "$tag" 8 | median) s, peak $(replay_stat "$tag" 9 | median) MB" ;;
            real_brain/sylvian_wide) extra="; $(replay_last "$tag" 10) contact vertices at the end" ;;
            sylvian | sylvian_noisy | sylvian_noisy_filtered) extra="; up to $(replay_stat "$tag" 14 | maximum) sub-steps a frame; force change a frame p95 $(replay_last "$tag" 15) N" ;;
        esac
        echo "| replay: $what, a frame | $(rp "$tag")$extra; $(runs_note) | $goal | $(code "${replay_cmd[$tag]}") |"
    done
    local none_p95 tethers_p95 tissue_p95 tethers_x tissue_x tethers_n
    none_p95=$(replay_p95 effects/none) tethers_p95=$(replay_p95 effects/tethers) tissue_p95=$(replay_p95 effects/tissue)
    tethers_x=$(ratio "$tethers_p95" "$none_p95")
    tissue_x=$(ratio "$tissue_p95" "$none_p95")
    tethers_n=$(hold_field effects/tethers '"%d bands, %d vessels" % (s["bands"]["total"], len(s["vessels"]))')
    echo "| what the effects cost on the fine-brain Sylvian opening, alternating run by run: frame p95 without them / with relaxation and ischemia (as shipped) / with its tethers ($tethers_n, \`sylvian_tethers.ron\`) | $none_p95 / $tissue_p95 / $tethers_p95 ms: tissue over time ${tissue_x}x, tethers ${tethers_x}x; $(runs_note); the rough opening with tethers p95 $(replay_p95 effects/tethers_rough) ms (max $(replay_max effects/tethers_rough) ms) | relaxation and ischemia within 1.2x: $(verdict "$tissue_x" 1.2); tethers within 1.3x: $(verdict "$tethers_x" 1.3); no frame over 50 ms: $(verdict "$(replay_max effects/tethers_rough)" 50) | $(code "fissure replay config/real_brain/sylvian.ron --set solver.cache_dir=None [--set '$plain_effects']") |"
    local hold_wall hold_p95 hold_risk int_risk hold_watch int_watch hold_ratio
    hold_wall=$(replay_stat hold/continuous 8 | tail -1)
    hold_p95=$(replay_p95 hold/continuous)
    hold_watch=$(hold_field hold/continuous 'round(s["ischemia"]["levels"][1]["final_area_mm2"], 1)')
    int_watch=$(hold_field hold/intermittent 'round(s["ischemia"]["levels"][1]["final_area_mm2"], 1)')
    hold_risk=$(hold_field hold/continuous 'round(s["ischemia"]["max_risk"], 3)')
    int_risk=$(hold_field hold/intermittent 'round(s["ischemia"]["max_risk"], 3)')
    echo "| ten minutes held on the fine-brain Sylvian scene ($(replay_stat hold/continuous 3 | tail -1) frames): whole run; frame p95; at the end, area at risk (risk >= 1/2) and the largest risk, continuous / intermittent (5 min, 1 min rest, 5 min) | $hold_wall s; p95 $hold_p95 ms; $hold_watch / $int_watch mm2, risk $hold_risk / $int_risk; one run each | a held frame costs next to nothing; the intermittent hold risks less: $( awk -v a="$int_watch" -v b="$hold_watch" -v c="$int_risk" -v d="$hold_risk" 'BEGIN { print ((a < b || (a == b && c < d)) ? "met" : "not met") }') | $(code "fissure replay config/real_brain/sylvian.ron --set solver.cache_dir=None --trajectory assets/trajectories/real_brain_sylvian_hold.csv --set duration_s=603.5") (\`_intermittent.csv\`, 668) |"
    local worst worst_tag
    # The rough opening with tethers has its own row (above).
    worst=$(awk -F'\t' '$1 != "effects/tethers_rough" { print $6 }' "$PERF/replays.tsv" | maximum)
    worst_tag=$(awk -F'\t' -v w="$worst" '$6 == w && $1 != "effects/tethers_rough" { print $1; exit }' "$PERF/replays.tsv")
    local band_x rows_x all_x surf_x
    band_x=$(ratio "$(replay_p50 size/fine)" "$(replay_p50 size/coarse)")
    rows_x=$(ratio "$(size_rows fine)" "$(size_rows coarse)")
    all_x=$(ratio "$(replay_p50 size/fine_all)" "$(replay_p50 size/coarse_all)")
    surf_x=$(ratio "$(size_surface fine)" "$(size_surface coarse)")
    echo "| the same blade motion on the coarse and the fine brain (the Sylvian scene as a user writes it), working region 10 mm beyond the ROI: frame p50 coarse / fine; fine over coarse, against its rows' ratio | $(replay_p50 size/coarse) / $(replay_p50 size/fine) ms; ${band_x}x for ${rows_x}x the rows ($(size_rows coarse) / $(size_rows fine)); with a row for every surface vertex ${all_x}x for ${surf_x}x ($(size_surface coarse) / $(size_surface fine)) | frame time follows the working region's rows, not the brain (docs/performance.md, "The same motion on the coarse and the fine brain") | $(code "fissure replay config/real_brain/sylvian.ron --set 'fixed=[LowestPerComponent(height_mm: 10.0)]' [--set 'mesh=File(coarse)'] [--set solver.row_band_mm=None]") |"
    echo "| longest frame of every replay above (the haptic loop reads the last answer) | $worst ms ($worst_tag) | no frame frozen > 50 ms: $(verdict "$worst" 50) | the replays above |"
    local cold_prob="solver.compliance_storage=F32"
    echo "| fine brain (q15, 62.8k nodes) cold, f32, every column first: model + factor / compliance precompute ($cold_rows rows x $cold_cols columns, $cold_mb MB) / peak memory | $cold_before s / $cold_compute s / $cold_peak MB | precompute < 60 s: $(verdict "$cold_compute" 60); < 2 GB: $(verdict "$cold_peak" 2048) | $(code "startup_probe config/real_brain/interhemispheric.ron 'mesh=File(q15)' $cold_prob 'solver.cache_dir=Some(DIR)'") (empty DIR) |"
    if [ "$FAST" != 1 ]; then
        echo "| the same cold start with early start (as the window): first frame; slowest frame; every column final | first frame $bgc_first s; slowest $bgc_slowest ms ($bgc_over50 over 50 ms); columns $bgc_columns s; peak $bgc_peak MB | first frame < 10 s: $(verdict "$bgc_first" 10) | the same with $(code solver.cache_dir=None --background) |"
    else
        echo "| the same cold start with early start (as the window): first frame | $NOT_RUN_FAST | first frame < 10 s | the same with $(code solver.cache_dir=None --background) |"
    fi
    echo "| fine brain from the cache: whole build (of which reading the file) / peak memory | $cache_build s ($cache_load s) / $cache_peak MB | reload < 1 s: $(verdict "$cache_load" 1); < 2 GB: $(verdict "$cache_peak" 2048) | the same command again (DIR now full) |"
    echo "| fine brain from the cache with early start: first frame; slowest frame | first frame $bgk_first s; slowest $bgk_slowest ms ($bgk_over50 over 50 ms) | first frame < 1 s: $(verdict "$bgk_first" 1) | the same with $(code --background) |"
    echo "| fine-brain Sylvian scene as shipped ($syl_rows rows x $syl_cols columns, $syl_mb MB), from the cache with early start: first frame | first frame $syl_first s (cold build $syl_cold_build s); peak $syl_peak MB | first frame < 1 s: $(verdict "$syl_first" 1) | $(code "startup_probe config/real_brain/sylvian.ron 'solver.cache_dir=Some(DIR)' --background") |"
    echo "| the same scene as a user writes it (no \`refine\`, so \`Auto\`; lowest 10 mm held, f64, no cache), every column first: compliance ($usr_rows rows x $usr_cols columns, $usr_mb MB); whole build; peak memory | $usr_compute s; $usr_build s; $usr_peak MB | build < 30 s: $(verdict "$usr_build" 30); < 2 GB: $(verdict "$usr_peak" 2048) | $(code "startup_probe config/real_brain/sylvian.ron 'fixed=[LowestPerComponent(height_mm: 10.0)]' solver.compliance_storage=F64 solver.cache_dir=None solver.early_start=false") |"
    echo "| the same scene opened as the window opens it (early start): first frame; frames that waited for their columns | first frame $usb_first s; slowest $usb_slowest ms ($usb_over50 over 50 ms); every column final $usb_columns s; peak $usb_peak MB | no frame over 50 ms: $( [ "$usb_over50" = 0 ] && echo met || echo "not met" ) | the same with $(code solver.early_start=true --background) |"
    if [ "$window_status" = ran ]; then
        window_figures "$PERF/window/threads_default.json"
        echo "| the window on the software renderer (Xvfb, llvmpipe on cores - 1 threads), default scene, blades held: fps; simulation step | $wfps fps; step p50 $wp50 / p95 $wp95 ms | step p95 < 2 ms: $(verdict "$wp95" 2) | $(code "fissure run config/sylvian.ron --exit-after 10 --size 1280x800") |"
    else
        echo "| the window on the software renderer (Xvfb): fps; simulation step | $window_status | step p95 < 2 ms | $(code "fissure run config/sylvian.ron --exit-after 10 --size 1280x800") |"
    fi
    echo "| exact FEM solve + surface update over the working region, paper-12k, f32, 100 / 300 constrained vertices (10 / 30 new a frame) | p95 $p_p95_100 / $p_p95_300 ms; at 300 ${p_two_x}x the floor of what the frame reads and factors ($p_two ms: W's new entries, W's factor, the working region's product), ${p_floor_x}x W's alone ($p_floor ms) | p95 < 3 ms at 300: $(verdict "$p_p95_300" 3); <= 2x the floor: $(at_most "$p_two_x" 2) | $(code "cargo bench --bench fem -- ${fem_models[*]}") |"
    if [ "$FAST" != 1 ]; then
        echo "| the same on the coarse real brain (hemispheres stored apart) | p95 $c_p95_100 / $c_p95_300 ms; at 300 ${c_two_x}x the floor ($c_two ms), ${c_floor_x}x W's alone ($c_floor ms) | <= 2x the floor: $(at_most "$c_two_x" 2) | the same |"
    else
        echo "| the same on the coarse real brain | $NOT_RUN_FAST | <= 2x the floor | the same |"
    fi
    echo "| compliance precompute / reload / peak memory (f32, 2 threads), paper-12k | $p_pre s / $p_reload s / $p_peak MB | < 60 s: $(verdict "$p_pre" 60); < 1 s: $(verdict "$p_reload" 1); < 2 GB: $(verdict "$p_peak" 2048) | the same |"
    if [ "$FAST" != 1 ]; then
        echo "| the same, coarse real brain | $c_pre s / $c_reload s / $c_peak MB | < 60 s: $(verdict "$c_pre" 60); < 1 s: $(verdict "$c_reload" 1); < 2 GB: $(verdict "$c_peak" 2048) | the same |"
        echo "| fill-reducing ordering: entries of L stored, AMD -> METIS nested dissection | paper-12k $p_amd -> $p_nd M; coarse brain $c_amd -> $c_nd M | the kept ordering (METIS) has fewer | the same (lines \"ordering\") |"
        echo "| f32 compliance against f64, 300 constrained: relative displacement / reaction error | paper-12k $p_err_u / $p_err_r; coarse brain $c_err_u / $c_err_r | < 1e-5: $(verdict "$(printf '%s\n%s\n' "$p_err_u" "$c_err_u" | maximum)" 1e-5) | the same |"
    else
        echo "| the same, coarse real brain | $NOT_RUN_FAST | < 60 s; < 1 s; < 2 GB | the same |"
        echo "| fill-reducing ordering: entries of L stored, AMD -> METIS nested dissection | paper-12k $p_amd -> $p_nd M | the kept ordering (METIS) has fewer | $(code "cargo bench --bench fem -- paper") |"
        echo "| f32 compliance against f64, 300 constrained: relative displacement / reaction error | paper-12k $p_err_u / $p_err_r | < 1e-5: $(verdict "$p_err_u" 1e-5) | $(code "cargo bench --bench fem -- paper") |"
    fi
    if [ "$FAST" != 1 ]; then
        local gains worst_gain
        gains=$(audit_gains_short)
        worst_gain=$(audit_gains | awk '{ print $2 }' | sort -g | head -1)
        echo "| what each per-frame optimisation of the exact solve buys: the phase it touches, with it against without, paper-12k and coarse brain (medians of three alternating rounds) | $gains | each kept one faster where it acts (slowest case ${worst_gain}x) | $(code "cargo bench --bench fem -- audit paper coarse") |"
    else
        echo "| what each per-frame optimisation of the exact solve buys | $NOT_RUN_FAST | each kept one faster where it acts | $(code "cargo bench --bench fem -- audit paper coarse") |"
    fi
    if [ "$cholmod_status" = ran ]; then
        echo "| our sparse Cholesky against CHOLMOD (METIS, one thread, median of rounds), coarse / fine brain: entries of L; numeric factor; 96-column solve | $(cholmod_ratio brain_pial_coarse metis exact)x / $(cholmod_ratio brain_pial_q15 metis exact)x; $(cholmod_ratio brain_pial_coarse metis numeric)x / $(cholmod_ratio brain_pial_q15 metis numeric)x; $(cholmod_ratio brain_pial_coarse metis solve)x / $(cholmod_ratio brain_pial_q15 metis solve)x | entries within 10 %; factor and solve <= 1.0x CHOLMOD's time | $(code bash scripts/cholmod_compare.sh) |"
    else
        echo "| our sparse Cholesky against CHOLMOD: entries of L; numeric factor; solve | $cholmod_status | entries within 10 %; factor and solve <= 1.0x CHOLMOD's time | $(code bash scripts/cholmod_compare.sh) |"
    fi
}
# One cell: each switch's range of gains over sequences and models.
audit_gains_short() {
    audit_gains |
        awk '{ if (!($1 in lo)) { order[++n] = $1; lo[$1] = $2; hi[$1] = $2 } if ($2 < lo[$1]) lo[$1] = $2; if ($2 > hi[$1]) hi[$1] = $2 }
             END { for (i = 1; i <= n; i++) { k = order[i]; printf "%s%s %s", (i > 1 ? "; " : ""), k, (lo[k] == hi[k] ? lo[k] "x" : lo[k] "-" hi[k] "x") } }'
}

# ---------------------------------------------------------------- the document

tmp="$PERF/performance.md.tmp"
{
    echo "# Performance"
    echo
    echo "Every figure on this page except the real-GPU table comes from one run of"
    echo "\`scripts/perf_docs.sh\` (release build): the machine, date and commit are"
    echo "below, and each row names its command (\`fissure\` is \`target/release/fissure\`,"
    echo "\`startup_probe\` is \`cargo run --release --example startup_probe --\`). The raw"
    echo "output of every measure is in \`target/perf/\` after a run. The machine is shared"
    echo "and a replay's p95 moves by 10-30 % from one hour to the next: compare figures"
    echo "measured in the same run."
    echo
    echo "- Machine: $cpu, $cores cores, $ram RAM"
    echo "- Date: $date_utc"
    echo "- Commit: $commit"
    echo "- Command: \`$command_line\`"
    echo
    echo "## Summary"
    echo
    echo "Each goal is the design's bar for the measure; \"met\" compares today's figure with it."
    echo
    echo "$SUMMARY_BEGIN"
    summary_rows
    echo "$SUMMARY_END"
    echo
    echo "## The collision stage per backend"
    echo
    echo "\`fissure bench collision --frames 30\` ($t_collision s). Two blades advance into"
    echo "the surface and the surface deforms to each frame's targets, so the later frames"
    echo "cast through contact. All backends of a case give the same answers (the last"
    echo "column hashes every frame's output; the command fails otherwise). \`bvh\` runs on"
    echo "its default 2 threads, \`bvh xN\` on every core; \`gpu\` sends the lines its"
    echo "candidates cannot decide to the CPU (column \"lines to CPU\"); \`reference\` is the"
    echo "brute force. \"cast / rest of stage\" splits a frame into the backend's own part"
    echo "(surface update and cast) and the part every backend shares (rays, candidate"
    echo "pairs, culling, targets). The GPU's own time comes from timestamp queries. Without"
    echo "a GPU the \`gpu\` rows run on Mesa's software Vulkan driver (llvmpipe), which shares"
    echo "the CPU cores with everything else."
    echo
    cat "$PERF/collision.md"
    grep '^note: ' "$PERF/collision.log" | sed 's/^note: /\nNote: /' || true
    echo
    echo "## Replays of the shipped scenes"
    echo
    echo "\`fissure replay SCENARIO --set solver.cache_dir=None\` for every scene in \`config/\`"
    echo "and \`config/real_brain/\` with a trajectory, $REPEAT run(s) each ($t_replays s in all); the"
    echo "wide press adds \`--trajectory assets/trajectories/real_brain_sylvian_wide.csv --set duration_s=4.5\`."
    echo "(\`config/study_fissure.ron\` has no trajectory: \`fissure study\` moves its blade.)"
    echo "Frame times come from \`summary.json\` (the replay's own clock, the precompute"
    echo "excluded); the whole run and its peak memory from \`/usr/bin/time\` (the"
    echo "precompute included); contact vertices (the surface vertices carrying a blade's"
    echo "force) and forces from the last row of \`metrics.csv\`, one figure a blade. The"
    echo "final state hashes every surface displacement bit: runs of the same build agree."
    echo
    echo "| scene | run | frames | frame p50 / p95 / max ms | stages p50 / p95 ms | whole run s | peak MB | contact vertices at the end | force at the end N | integrity | final state |"
    echo "|---|---:|---:|---|---|---:|---:|---|---|---|---|"
    awk -F'\t' '{ printf "| %s | %s | %s | %s / %s / %s | %s | %s | %s | %s | %s | %s | %s |\n", $1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, substr($13, 1, 8) }' "$PERF/replays.tsv"
    echo
    echo "## The same motion on the coarse and the fine brain"
    echo
    echo "The fine-brain Sylvian scene as a user writes it (\`--set 'fixed=[LowestPerComponent(height_mm: 10.0)]'\`: no \`refine\`, so \`Auto\`), its"
    echo "motion replayed on the fine brain (q15) and on the coarse one (\`--set '$coarse_mesh'\`),"
    echo "each with the working region's rows (the default \`solver.row_band_mm\`, 10 mm"
    echo "beyond the region of interest) and with a row for every surface vertex"
    echo "(\`--set solver.row_band_mm=None\`); $REPEAT run(s) each, medians. The region"
    echo "is the same in millimetres on both brains; the fine brain has more vertices in it, except where \`Auto\` refined both to the same edge."
    echo
    echo "| brain | rows x columns, working region | frame p50 / p95 ms | rows, every surface vertex | frame p50 / p95 ms |"
    echo "|---|---|---|---|---|"
    for brain in coarse fine; do
        echo "| $brain | $(size_rows "$brain") x $(size_cols "$brain") | $(replay_p50 "size/$brain") / $(replay_p95 "size/$brain") | $(size_rows "${brain}_all") | $(replay_p50 "size/${brain}_all") / $(replay_p95 "size/${brain}_all") |"
    done
    echo
    echo "## Startup"
    echo
    echo "\`examples/startup_probe.rs\` ($t_startup s in all): a scene's build (mesh, model,"
    echo "factor, compliance) and what it keeps; with \`--background\` the build returns"
    echo "after the factor and the compliance columns fill in the background while the"
    echo "scene's motion runs, as the window does with \`solver.early_start\` (the shipped"
    echo "scenes set it). Times are from the process's start. The fine brain is the"
    echo "inter-hemispheric scene on q15 (\`$Q15_MESH\`),"
    echo "f32 storage. Each cold run starts with an empty cache folder or none."
    echo
    echo "| run | command (after \`startup_probe\`) | figures |"
    echo "|---|---|---|"
    echo "| fine brain, cold | \`config/real_brain/interhemispheric.ron 'mesh=File(q15)' solver.compliance_storage=F32 'solver.cache_dir=Some(DIR)'\` | model + factor $cold_before s; compliance $cold_rows rows x $cold_cols columns, $cold_mb MB, computed in $cold_compute s; build done $cold_build s (the cache file written); peak $cold_peak MB |"
    if [ "$FAST" != 1 ]; then
        echo "| fine brain, cold, early start | the same with \`solver.cache_dir=None --background\` | first frame $bgc_first s; $bgc_frames frames done $bgc_motion s; slowest frame $bgc_slowest ms, $bgc_over50 over 50 ms (those waiting for their columns); every column final $bgc_columns s; peak $bgc_peak MB |"
    else
        echo "| fine brain, cold, early start | the same with \`solver.cache_dir=None --background\` | $NOT_RUN_FAST |"
    fi
    echo "| fine brain from the cache | the first command again | build done $cache_build s, of which reading the file $cache_load s; peak $cache_peak MB |"
    echo "| fine brain from the cache, early start | the same with \`--background\` | first frame $bgk_first s; $bgk_frames frames done $bgk_motion s; slowest frame $bgk_slowest ms, $bgk_over50 over 50 ms; every column read $bgk_columns s; peak $bgk_peak MB |"
    echo "| fine-brain Sylvian scene as shipped, cold | \`config/real_brain/sylvian.ron 'solver.cache_dir=Some(DIR)'\` | refined mesh, $syl_rows rows x $syl_cols columns, $syl_mb MB; build done $syl_cold_build s; peak $syl_cold_peak MB |"
    echo "| the same from the cache, early start | the same with \`--background\` | first frame $syl_first s; slowest frame $syl_slowest ms, $syl_over50 over 50 ms; every column read $syl_columns s; peak $syl_peak MB |"
    echo "| the same scene as a user writes it, cold | \`config/real_brain/sylvian.ron 'fixed=[LowestPerComponent(height_mm: 10.0)]' solver.compliance_storage=F64 solver.cache_dir=None solver.early_start=false\` | model + factor $usr_before s; compliance $usr_rows rows x $usr_cols columns, $usr_mb MB, computed in $usr_compute s; build done $usr_build s; peak $usr_peak MB |"
    echo "| the same scene as a user writes it, cold, early start | the same with \`solver.early_start=true --background\` | first frame $usb_first s; $usb_frames frames done $usb_motion s; slowest frame $usb_slowest ms, $usb_over50 over 50 ms (those waiting for their columns); every column final $usb_columns s; peak $usb_peak MB |"
    echo
    echo "## The window's frame time"
    echo
    echo "The simulation runs on its own thread; the window draws what it last finished."
    echo "On a machine without a GPU, Mesa's llvmpipe draws the window on the CPU and"
    echo "takes cores from the simulation, so \`fissure run\` and the bare \`fissure\` set"
    echo "\`LP_NUM_THREADS\` to the number of cores minus one unless it is already set (a"
    echo "real GPU's driver never reads it): the drawing slows, the simulation keeps its pace."
    echo
    if [ "$window_status" = ran ]; then
        echo "Under Xvfb, \`fissure run config/sylvian.ron --exit-after 10 --size 1280x800\`"
        echo "with the blades held, from a filled compliance cache (a first run, not counted, fills it):"
        echo
        echo "| llvmpipe threads | window fps | simulation step p50 / p95 ms | adapter |"
        echo "|---|---:|---|---|"
        window_figures "$PERF/window/threads_default.json"
        echo "| cores - 1 (what \`fissure run\` sets) | $wfps | $wp50 / $wp95 | ${wadapter:-not named} |"
        window_figures "$PERF/window/threads_all.json"
        echo "| $cores (\`LP_NUM_THREADS=$cores\`: every core) | $wfps | $wp50 / $wp95 | ${wadapter:-not named} |"
    else
        echo "The window was $window_status."
    fi
    echo
    echo "## The exact FEM solve"
    echo
    echo "\`cargo bench --bench fem -- ${fem_models[*]}\` ($t_fem s with the audit below): for each model, the"
    echo "scene-independent solver on a window of constrained vertices sliding over the"
    echo "surface (100 / 300 constrained, 10 / 30 new a frame), f32 compliance reloaded"
    echo "from the cache, its rows the working region's (the surface within the default"
    echo "\`solver.row_band_mm\` of the ROI, as a scene stores them). The floors are measured"
    echo "in the same run: W's floor is reading W's new entries plus the cheapest dense"
    echo "Cholesky of W; the product floor is reading every stored row of the constrained"
    echo "columns once at this machine's streaming rate; what the frame reads and factors"
    echo "is their sum."
    echo
    echo "| | paper-12k | coarse real brain |"
    echo "|---|---|---|"
    cf() { if [ "$FAST" = 1 ]; then echo "$NOT_RUN_FAST"; else echo "$1"; fi; }
    echo "| nodes | $p_nodes | $(cf "${c_nodes:-}") |"
    echo "| model + factor (total) | $p_factor s | $(cf "${c_factor:-} s") |"
    echo "| entries of L stored (counted exactly), AMD -> METIS | $p_amd ($p_amd_exact) -> $p_nd ($p_nd_exact) M; METIS's 96-column solve ${p_nd_solve}x AMD's | $(cf "${c_amd:-} (${c_amd_exact:-}) -> ${c_nd:-} (${c_nd_exact:-}) M; ${c_nd_solve:-}x") |"
    echo "| compliance (f32): size, precompute, reload | $p_rows x $p_cols, $p_mb MB; $p_pre s; $p_reload s | $(cf "${c_rows:-} x ${c_cols:-}, ${c_mb:-} MB; ${c_pre:-} s; ${c_reload:-} s") |"
    echo "| frame p50 / p95, 100 constrained | $p_p50_100 / $p_p95_100 ms | $(cf "${c_p50_100:-} / ${c_p95_100:-} ms") |"
    echo "| frame p50 / p95, 300 constrained | $p_p50_300 / $p_p95_300 ms | $(cf "${c_p50_300:-} / ${c_p95_300:-} ms") |"
    echo "| at 300: the floor; frame p95 against it | $p_floor ms; ${p_floor_x}x | $(cf "${c_floor:-} ms; ${c_floor_x:-}x") |"
    echo "| at 300: the surface product against its floor (streaming at this rate) | $p_product ms against $p_product_floor ms ($p_stream GB/s) | $(cf "${c_product:-} ms against ${c_product_floor:-} ms (${c_stream:-} GB/s)") |"
    echo "| at 300: frame p95 against both floors | ${p_two_x}x ($p_two ms) | $(cf "${c_two_x:-}x (${c_two:-} ms)") |"
    echo "| f32 against f64 at 300: displacement / reaction error | $p_err_u / $p_err_r | $(cf "${c_err_u:-} / ${c_err_r:-}") |"
    echo "| peak resident memory (the process so far) | $p_peak MB | $(cf "${c_peak:-} MB") |"
    echo
    echo "How the frame grows with the contact set (the bench writes the plot and its CSV"
    echo "to \`target/fem-bench-cache/sweep/\`): the surface product grows with the"
    echo "constrained vertices, the W factor with their cube."
    echo
    echo "![frame time against constrained vertices](images/fem_constrained_sweep.png)"
    echo
    echo "## What each per-frame optimisation buys"
    echo
    if [ "$FAST" != 1 ]; then
        echo "\`cargo bench --bench fem -- audit ${fem_models[*]}\`: each optimisation that"
        echo "\`fem::tuning\` can switch off (\`FISSURE_FEM_OFF=name\`), on and off in the same"
        echo "run, alternating, three rounds (the medians), on 300 constrained vertices held,"
        echo "growing by 30 a frame, and sliding by 30 a frame; the phase it touches, on -> off."
        echo "The scene-level switches and huge pages are measured by \`bash scripts/fem_audit.sh\`;"
        echo "docs/design-notes.md says why each optimisation is kept."
        echo
        echo '```text'
        grep -E '^(== |audit)' "$PERF/fem_audit.log" | grep -v '^audit plot'
        echo '```'
        echo
        echo "![what each fem optimisation buys, paper-12k](images/fem_audit_paper12k.png)"
        echo "![what each fem optimisation buys, coarse brain](images/fem_audit_coarse_brain.png)"
    else
        echo "$NOT_RUN_FAST."
    fi
    echo
    echo "## Our sparse Cholesky beside CHOLMOD"
    echo
    if [ "$cholmod_status" = ran ]; then
        echo "\`bash scripts/cholmod_compare.sh\` ($t_cholmod s): the stiffness K_FF of each real"
        echo "brain factored by fissure (\`examples/factor_compare.rs\`) and by CHOLMOD, each"
        echo "with METIS and with AMD, one thread, best of 3 a round, rounds alternating."
        echo "Medians over the rounds of ours / CHOLMOD's:"
        echo
        echo "| mesh | ordering | entries of L (exact) | numeric factor | 96-column solve |"
        echo "|---|---|---:|---:|---:|"
        for m in brain_pial_coarse brain_pial_q15; do
            for o in metis amd; do
                echo "| $m | $o | $(cholmod_ratio $m $o exact)x | $(cholmod_ratio $m $o numeric)x | $(cholmod_ratio $m $o solve)x |"
            done
        done
        echo
        echo '```text'
        cat "$PERF/cholmod.log"
        echo '```'
    else
        echo "\`bash scripts/cholmod_compare.sh\`: $cholmod_status."
    fi
    echo
    echo "## The collision stage on a real GPU"
    echo
    echo "Only a machine with a GPU can measure this (\`bash scripts/gpu_devkit.sh\` packs"
    echo "what it needs); \`scripts/perf_docs.sh\` keeps this section as it finds it."
    echo
    cat "$PERF/gpu_section.md"
} > "$tmp"
[ "$(grep -cxF "$SUMMARY_BEGIN" "$tmp")" = 1 ] || die "the new $DOC has no single summary block"
mv "$tmp" "$DOC"
for png in fem_constrained_sweep fem_audit_paper12k fem_audit_coarse_brain; do
    if [ -f "$PERF/$png.png" ]; then cp -f "$PERF/$png.png" "docs/images/$png.png"; fi
done
copy_summary_to_readme
log "wrote $DOC in $(((SECONDS - t_script) / 60)) min $(((SECONDS - t_script) % 60)) s (collision ${t_collision} s, replays ${t_replays} s, startup ${t_startup} s, window ${t_window} s, fem ${t_fem} s, CHOLMOD ${t_cholmod} s)"
