#!/usr/bin/env bash
# The whole Lightport test suite. Installs what it needs on a fresh Debian machine.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n==> %s\n' "$*"; }

# The GL backend's tests need a GL driver: Mesa's EGL, GLES and software rasteriser (llvmpipe).
missing=()
for package in libegl1 libegl-mesa0 libgles2 libgl1-mesa-dri; do
    status=$(dpkg-query -W -f='${Status}' "$package" 2>/dev/null || true)
    [ "$status" = "install ok installed" ] || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
    step "installing ${missing[*]}"
    sudo=()
    if [ "$(id -u)" -ne 0 ]; then sudo=(sudo); fi
    "${sudo[@]}" apt-get update
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing[@]}"
fi

step "toolchain components"
rustup component add rustfmt clippy >/dev/null 2>&1 || true

step "format"
cargo fmt --all -- --check

step "clippy"
cargo clippy --workspace --all-targets -- -D warnings

step "generated shaders are fresh"
cargo run -q -- shaders --check >/dev/null || cargo run -q -- shaders --check

step "tests"
cargo test --workspace --all-targets
cargo test --workspace --doc
