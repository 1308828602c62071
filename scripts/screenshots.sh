#!/usr/bin/env bash
# Re-renders every picture the README and docs/ show with `fissure screenshot`,
# each by the exact command printed under it (found as a backquoted
# `fissure screenshot ... -o docs/images/NAME.png ...` in README.md and
# docs/*.md). Run it when a change moves what a scene looks like, look at the
# PNGs, and commit them. Offscreen rendering: the software Vulkan driver is
# enough (no display). Release build.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
export VK_DRIVER_FILES="${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.x86_64.json}"
mapfile -t commands < <(grep -ho '`fissure screenshot [^`]* -o docs/images/[^` ]*\.png[^`]*`' README.md docs/*.md | tr -d '`' | sort -u)
[ "${#commands[@]}" -gt 0 ] || { echo "screenshots.sh: no screenshot commands found in README.md or docs/*.md" >&2; exit 1; }
for c in "${commands[@]}"; do
    echo "$c"
    # The command's words as written (no quoting inside these commands).
    read -r -a words <<< "${c#fissure }"
    target/release/fissure "${words[@]}" > /dev/null
done
echo "screenshots.sh: ${#commands[@]} pictures re-rendered"
