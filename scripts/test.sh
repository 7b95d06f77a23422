#!/usr/bin/env bash
# The whole Lightport test suite. Installs what it needs on a fresh Debian machine.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n==> %s\n' "$*"; }

# The GL backend's tests need a GL driver: Mesa's EGL, GLES and software rasteriser (llvmpipe).
# The wgpu backend's tests (tests/rendering/wgpu.rs) need a Vulkan driver: Mesa lavapipe and the loader.
# The web tests (tests/cli/web.rs) need Chromium (WebGL2 on SwiftShader) and node + npm to drive it.
# tests/cli/export.rs serves an exported site with nginx.
missing=()
for package in libegl1 libegl-mesa0 libgles2 libgl1-mesa-dri mesa-vulkan-drivers libvulkan1 chromium nginx; do
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
# The FBX loader builds the ufbx C library (the `cc` crate): a C compiler and the C library's
# headers. rustc already links through `cc`, but `--no-install-recommends` leaves libc6-dev out.
if ! command -v cc >/dev/null || [ ! -e /usr/include/stdlib.h ]; then
    step "installing gcc libc6-dev"
    sudo=()
    if [ "$(id -u)" -ne 0 ]; then sudo=(sudo); fi
    "${sudo[@]}" apt-get update
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends gcc libc6-dev
fi
if ! command -v npm >/dev/null; then
    step "installing nodejs npm"
    sudo=()
    if [ "$(id -u)" -ne 0 ]; then sudo=(sudo); fi
    "${sudo[@]}" apt-get update
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends nodejs npm
fi

# A fresh clone builds once: incremental state would only double the disk the build takes.
export CARGO_INCREMENTAL=0

step "browser test driver (npm ci in tests/web)"
(cd tests/web && npm ci --no-audit --no-fund)

step "web build (wasm32 + wasm-bindgen into web/pkg)"
scripts/build-web.sh

step "toolchain components"
rustup component add rustfmt clippy >/dev/null 2>&1 || true

step "format"
cargo fmt --all -- --check

step "clippy"
cargo clippy --workspace --all-targets -- -D warnings
cargo clippy -p lightport-web --target wasm32-unknown-unknown -- -D warnings

step "tests"
# Every process the tests start carries this marker in its environment, so that any left running
# afterwards is found (scripts/leftover-processes.sh), whether the tests passed or not.
session="$$-$(date +%s%N)"
status=0
# One invocation: libraries, binaries, integration tests and doc tests share one build (a
# separate `--doc` run resolved other features and rebuilt half the workspace, ~1.5 min), and
# every failing test binary is reported, not only the first. That shaders-generated/ is fresh is
# a test (tests/kernel/codegen.rs): a separate `cargo run -- shaders --check` resolved the binary's
# features alone and built many dependencies a second time (~15 min on 2 cores, cold).
LIGHTPORT_TEST_SESSION=$session cargo test --workspace --no-fail-fast || status=$?

step "no process outlives the tests"
scripts/leftover-processes.sh "$session" || status=1
exit "$status"
