#!/usr/bin/env bash
# Checks the Rust toolchain (cargo, Rust >= 1.95: says how to get it when
# missing) and installs the Debian packages fissure needs to build and to run headless:
# a software Vulkan driver (Mesa lavapipe), Xvfb for the window test, udev and
# pkg-config for gilrs, and the X libraries winit loads. Idempotent and quiet
# when everything is present. Without root (and no sudo) it prints exactly
# which packages are missing and exits 1.
set -euo pipefail
required_rust="1.95"
if ! command -v cargo >/dev/null 2>&1; then
  echo "fissure needs Rust $required_rust or newer, and cargo is not on PATH. Install it with:" >&2
  echo "  curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs | sh -s -- -y && source \"\$HOME/.cargo/env\"" >&2
  exit 1
fi
have_rust="$(rustc --version | awk '{print $2}')"
if [ "$(printf '%s\n%s\n' "$required_rust" "$have_rust" | sort -V | head -n1)" != "$required_rust" ]; then
  echo "fissure needs Rust $required_rust or newer; this machine has $have_rust. Update with: rustup update stable" >&2
  exit 1
fi
packages=(mesa-vulkan-drivers libvulkan1 xvfb xauth libx11-xcb1 libxkbcommon-x11-0 libxcursor1 libxi6
          libxrandr2 libudev-dev pkg-config)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
if [ "$(id -u)" -eq 0 ]; then SUDO=""; elif command -v sudo >/dev/null; then SUDO="sudo"; else
  echo "fissure needs these Debian packages: ${missing[*]}" >&2
  echo "install them with: apt-get install ${missing[*]}" >&2
  exit 1
fi
echo "installing: ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq >&2
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
