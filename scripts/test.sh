#!/usr/bin/env bash
# The whole Lightport test suite. Installs what it needs on a fresh Debian machine.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n==> %s\n' "$*"; }

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
