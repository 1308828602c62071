#!/usr/bin/env bash
# Runs every performance measure of fissure in one go; examples/perf_page.rs
# then renders docs/performance.md from what they wrote (each program's JSON,
# read as its own type from fissure::perf::reports): the machine, date, commit
# and command at the top, a summary table (one row a measure: today's figure,
# its goal, its command) between the performance-summary markers, then each
# measure's full section. The same summary is copied into README.md between
# the same markers (tests/suite/performance_doc.rs holds the two equal). This
# script only builds, runs, times (/usr/bin/time) and starts Xvfb; it reads
# no figure itself.
#
#   scripts/perf_docs.sh            # every measure, about 20 minutes on 2 cores
#   FAST=1 scripts/perf_docs.sh     # one run a replay; no fem audit, no coarse-brain
#                                   # fem bench, no cold early start, no CHOLMOD: under 8 minutes
#   scripts/perf_docs.sh --readme   # only copy docs/performance.md's summary into README.md
#
# Environment: FAST=1 (above); REPEAT=N replays each scene N times (default 3,
# 1 with FAST=1; the summary gives the medians).
#
# Measures, in order (what each wrote is kept in target/perf/, the page's
# source; `perf_page` renders the page from it again without measuring):
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
# gpu-table markers is carried through from the docs/performance.md already
# there; a run of scripts/gpu_devkit.sh on a GPU machine replaces it.
#
# Any measure that fails stops the script with a non-zero exit naming it, and
# so does a figure the page needs that a measure did not write;
# docs/performance.md and README.md are only replaced once every figure is
# there (each written whole).
set -euo pipefail
cd "$(dirname "$0")/.."

log() { printf '[perf_docs %s] %s\n' "$(date -u +%H:%M:%S)" "$*" >&2; }
die() {
    printf 'perf_docs: FAILED: %s\n' "$*" >&2
    exit 1
}

case "${1:-}" in
    --readme)
        cargo run --release --quiet --example perf_page -- --readme-only || die "copying the summary into README.md"
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
}
trap cleanup EXIT

# ---------------------------------------------------------------- start

t_script=$SECONDS
rm -rf "$PERF"
mkdir -p "$PERF"
: > "$PERF/seconds.tsv"

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
echo "collision $((SECONDS - t0))" >> "$PERF/seconds.tsv"

# ---------------------------------------------------------------- 2. replays

t0=$SECONDS
mkdir -p "$PERF/replay"
# One line a run in replays.tsv: tag, run, the command as the page shows it, and its folder under $PERF
# (summary.json, metrics.csv; the process's wall time and peak memory in FOLDER.time).
: > "$PERF/replays.tsv"
# replay_once TAG K SCENARIO [ARGS..]: run K of one scene.
replay_once() {
    local tag=$1 k=$2 scenario=$3
    shift 3
    local dir="replay/${tag//\//_}_$k"
    local base="$PERF/$dir"
    rm -rf "$base"
    run_timed "replay $tag (run $k of $REPEAT)" "$base.log" "$base.time" \
        "$FISSURE" replay "$scenario" --set solver.cache_dir=None "$@" --out "$base"
    printf '%s\t%s\t%s\t%s\n' "$tag" "$k" "fissure replay $scenario --set solver.cache_dir=None${*:+ $*}" "$dir" >> "$PERF/replays.tsv"
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
# The default scene on the phantom's own mesh (`refine: None`): what refining under the blades costs.
replay unrefined/sylvian config/sylvian.ron --set refine=None
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
echo "replays $((SECONDS - t0))" >> "$PERF/seconds.tsv"

# ---------------------------------------------------------------- 3. startup

t0=$SECONDS
mkdir -p "$PERF/startup"
q15_cache="$PERF/startup/cache_q15"
sylvian_cache="$PERF/startup/cache_sylvian"
rm -rf "$q15_cache" "$sylvian_cache"
probe_q15=("$PROBE" config/real_brain/interhemispheric.ron "$Q15_MESH" solver.compliance_storage=F32)
# probe NAME WHAT ARGS..: one run of the startup probe, its figures in startup/NAME.json.
probe() {
    local name=$1 what=$2
    shift 2
    run_measure "startup: $what" "$PERF/startup/$name.log" "$@" --json "$PERF/startup/$name.json"
}
# A. Cold, the build that computes every column first; it writes the cache the next runs read.
probe q15_cold "fine brain cold" "${probe_q15[@]}" "solver.cache_dir=Some(\"$q15_cache\")"
# B. Cold with early start, as the window runs it (no cache).
if [ "$FAST" != 1 ]; then
    probe q15_cold_background "fine brain cold, early start" "${probe_q15[@]}" solver.cache_dir=None --background
fi
# C, D. From the cache, without and with early start.
probe q15_cache "fine brain from the cache" "${probe_q15[@]}" "solver.cache_dir=Some(\"$q15_cache\")"
probe q15_cache_background "fine brain from the cache, early start" "${probe_q15[@]}" "solver.cache_dir=Some(\"$q15_cache\")" --background
# E, F. The fine-brain Sylvian scene as shipped: cold (writes its cache), then from the cache with early start.
probe sylvian_cold "fine-brain Sylvian scene cold" "$PROBE" config/real_brain/sylvian.ron "solver.cache_dir=Some(\"$sylvian_cache\")"
probe sylvian_cache_background "fine-brain Sylvian scene from the cache, early start" "$PROBE" config/real_brain/sylvian.ron "solver.cache_dir=Some(\"$sylvian_cache\")" --background
# G. The same scene as a user writes it: no `refine` (so `Auto`), only the lowest 10 mm held, f64, no cache.
user_sylvian=("fixed=[LowestPerComponent(height_mm: 10.0)]" solver.compliance_storage=F64 solver.cache_dir=None solver.early_start=false)
probe user_sylvian_cold "a user's fine-brain Sylvian scene cold" "$PROBE" config/real_brain/sylvian.ron "${user_sylvian[@]}"
# H. The same opened as the window opens it (early start): the frames that wait for their columns.
probe user_sylvian_background "a user's fine-brain Sylvian scene cold, early start" "$PROBE" config/real_brain/sylvian.ron "${user_sylvian[@]}" solver.early_start=true --background
echo "startup $((SECONDS - t0))" >> "$PERF/seconds.tsv"

# ---------------------------------------------------------------- 4. the window

t0=$SECONDS
page_flags=()
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
    # Only a window writes --report: a run that fell back to headless leaves no JSON, and the page says so.
    run_measure "window: warm-up" "$PERF/window/warmup.log" env DISPLAY="$display" timeout 180 "$FISSURE" "${window_args[@]}" --exit-after 20
    window_args+=(--exit-after 10)
    run_measure "window: llvmpipe on cores - 1 threads" "$PERF/window/threads_default.log" env -u LP_NUM_THREADS DISPLAY="$display" timeout 180 "$FISSURE" "${window_args[@]}" --report "$PERF/window/threads_default.json"
    run_measure "window: llvmpipe on every core" "$PERF/window/threads_all.log" env LP_NUM_THREADS="$cores" DISPLAY="$display" timeout 180 "$FISSURE" "${window_args[@]}" --report "$PERF/window/threads_all.json"
    kill "$xvfb_pid" 2> /dev/null || true
    xvfb_pid=""
else
    page_flags+=(--no-window)
fi
echo "window $((SECONDS - t0))" >> "$PERF/seconds.tsv"

# ---------------------------------------------------------------- 5. fem bench

t0=$SECONDS
fem_models=(paper coarse)
[ "$FAST" = 1 ] && fem_models=(paper)
rm -rf target/fem-bench-cache/figures
run_measure "fem bench" "$PERF/fem.log" cargo bench --quiet --bench fem -- "${fem_models[@]}"
cp -f target/fem-bench-cache/sweep/paper-12k_constrained_sweep.png "$PERF/fem_constrained_sweep.png" 2> /dev/null || true
if [ "$FAST" != 1 ]; then
    run_measure "fem bench audit" "$PERF/fem_audit.log" cargo bench --quiet --bench fem -- audit "${fem_models[@]}"
    cp -f target/fem-bench-cache/audit/paper-12k_audit.png "$PERF/fem_audit_paper12k.png" 2> /dev/null || true
    cp -f target/fem-bench-cache/audit/brain_pial_coarse_audit.png "$PERF/fem_audit_coarse_brain.png" 2> /dev/null || true
fi
echo "fem $((SECONDS - t0))" >> "$PERF/seconds.tsv"

# ---------------------------------------------------------------- 6. CHOLMOD

t0=$SECONDS
if [ "$FAST" != 1 ] && [ -f /usr/include/suitesparse/cholmod.h ]; then
    run_measure "CHOLMOD comparison" "$PERF/cholmod.log" bash scripts/cholmod_compare.sh
else
    page_flags+=(--no-cholmod)
fi
echo "cholmod $((SECONDS - t0))" >> "$PERF/seconds.tsv"

# ---------------------------------------------------------------- the page

[ "$FAST" = 1 ] && page_flags+=(--fast)
run_measure "the page (examples/perf_page.rs)" "$PERF/page.log" target/release/examples/perf_page \
    --dir "$PERF" --fem target/fem-bench-cache/figures --machine "$cpu, $cores cores, $ram RAM" --date "$date_utc" \
    --commit "$commit" --command "$command_line" --repeat "$REPEAT" --cores "$cores" "${page_flags[@]}"
for png in fem_constrained_sweep fem_audit_paper12k fem_audit_coarse_brain; do
    if [ -f "$PERF/$png.png" ]; then cp -f "$PERF/$png.png" "docs/images/$png.png"; fi
done
log "wrote docs/performance.md and README.md's summary in $(((SECONDS - t_script) / 60)) min $(((SECONDS - t_script) % 60)) s"
