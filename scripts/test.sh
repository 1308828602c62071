#!/usr/bin/env bash
# Runs fissure's whole test suite (debug profile, no GPU or display needed):
# installs the Debian packages (scripts/deps.sh, which also checks the Rust toolchain),
# points wgpu at the software Vulkan driver (Mesa lavapipe), then
# builds every target (benches included, in the test profile: they must compile,
# but performance lives in `cargo bench`, not in the suite), runs the library,
# binary and integration tests, then the doc tests. Extra arguments go to the
# cargo test runs.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
export VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
export WGPU_BACKEND=vulkan
XDG_RUNTIME_DIR="$(mktemp -d)"
export XDG_RUNTIME_DIR
trap 'rm -rf "$XDG_RUNTIME_DIR"' EXIT
cargo test --all-targets --no-run --quiet
# `--tests`: the targets built above and no more (a plain `cargo test` would
# build the examples once again outside the test harness, and run the doc tests twice).
cargo test --tests "$@"
cargo test --doc "$@"
