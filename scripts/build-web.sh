#!/usr/bin/env bash
# Builds the browser path tracer: the `lightport-web` crate for wasm32 (release), wrapped by
# wasm-bindgen (`--target web`) into web/pkg/, which `lightport serve` serves under /pkg/.
# Installs what it needs: the wasm32 target and wasm-bindgen-cli at exactly the version of the
# wasm-bindgen crate in Cargo.lock (the two must match).
#
# Respects CARGO_TARGET_DIR.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n==> %s\n' "$*"; }

if ! rustup target list --installed | grep -qx wasm32-unknown-unknown; then
    step "installing the wasm32-unknown-unknown target"
    rustup target add wasm32-unknown-unknown
fi

# The version of the `wasm-bindgen` package in Cargo.lock.
version=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
if [ -z "$version" ]; then
    echo "error: Cargo.lock has no wasm-bindgen package (is web/ a workspace member?)" >&2
    exit 1
fi
installed=$(wasm-bindgen --version 2>/dev/null | awk '{ print $2 }' || true)
if [ "$installed" != "$version" ]; then
    step "installing wasm-bindgen-cli $version (found: ${installed:-none})"
    cargo install wasm-bindgen-cli --version "$version" --force
fi

target_dir=${CARGO_TARGET_DIR:-target}
step "building lightport-web for wasm32 (release)"
cargo build -p lightport-web --lib --release --target wasm32-unknown-unknown

step "wasm-bindgen --target web -> web/pkg/"
rm -rf web/pkg
wasm-bindgen --target web --no-typescript --out-dir web/pkg \
    "$target_dir/wasm32-unknown-unknown/release/lightport_web.wasm"
ls -l web/pkg
