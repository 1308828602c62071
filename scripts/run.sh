#!/usr/bin/env bash
# Runs the fissure binary in release mode: installs the Debian packages
# (scripts/deps.sh, which also checks the Rust toolchain), then `cargo run --release --`
# with the given arguments. With none, fissure runs the default scene
# (config/sylvian.ron).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
export VK_DRIVER_FILES="${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.x86_64.json}"
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
  XDG_RUNTIME_DIR="$(mktemp -d)"
  export XDG_RUNTIME_DIR
fi
exec cargo run --release -- "$@"
