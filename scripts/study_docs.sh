#!/usr/bin/env bash
# Regenerates the committed study reports and the README's study section:
#   docs/study/quick/  `fissure study --preset quick` (report.md and its plots; the README copies its summary)
#   docs/study/ci/     `fissure study --preset ci` (the test suite re-runs it and compares its accuracy columns)
#   docs/study/brain/  `fissure study --preset brain` (the shipped real brains, assets/brain/)
# The reference runs are kept in target/study-cache between regenerations by the same build (their times are
# then those of the run that made them; any code change, hence a new binary, runs them again).
# Release build; takes several minutes on 2 cores. Run it when a change moves the study's numbers
# (tests/suite/study_quick.rs says so) and commit the result.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
presets="${PRESETS:-quick ci brain}"
for preset in $presets; do
    out="$(mktemp -d)"
    target/release/fissure study --preset "$preset" --out "$out" --cache-dir target/study-cache
    mkdir -p "docs/study/$preset"
    cp "$out/report.md" "$out"/*.png "docs/study/$preset/"
    rm -rf "$out"
done
# The README's section between the summary markers becomes the quick report's.
begin='<!-- study summary: begin -->'
end='<!-- study summary: end -->'
awk -v b="$begin" -v e="$end" -v src="docs/study/quick/report.md" '
    BEGIN { while ((getline line < src) > 0) { if (line == b) on = 1; else if (line == e) on = 0; else if (on) summary = summary line "\n" } }
    $0 == b { print; printf "%s", summary; skip = 1; next }
    $0 == e { skip = 0 }
    !skip { print }
' README.md > README.md.tmp
mv README.md.tmp README.md
echo "docs/study/quick, docs/study/ci and README.md's study section regenerated"
