#!/usr/bin/env bash
# Coverage-guided fuzzing of one Lightport target with libFuzzer, on the stable toolchain.
#
#   scripts/fuzz.sh TARGET [libFuzzer options...]     e.g.  scripts/fuzz.sh gltf -runs=1000000
#
# Targets: gltf obj texture sky bundle http (see docs/fuzzing.md). The binaries are built with
# SanitizerCoverage (rustc's -Cpasses=sancov-module; no cargo-fuzz, no nightly) into
# target/<host triple>/release (host builds are untouched). The corpus grows in
# fuzz/corpus/TARGET (seeded from tests/data, or $LIGHTPORT_SHARED, and fuzz/regressions/TARGET); findings land
# in fuzz/artifacts/TARGET. Each input runs under a time bound (-timeout, a hang is a finding)
# and the process under an RSS limit (-rss_limit_mb).
set -euo pipefail
cd "$(dirname "$0")/.."
target=${1:?usage: scripts/fuzz.sh TARGET [libFuzzer options...]}
shift
triple=$(rustc -vV | sed -n 's/^host: //p')

export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks"
# --target keeps the coverage flags off build scripts and proc macros (they cannot link them).
cargo build --release -p lightport-fuzz --features libfuzzer --bin "$target" --target "$triple"
unset RUSTFLAGS
if [ "$target" = http ]; then
    # The server the HTTP target talks to: the ordinary debug build.
    cargo build -q --bin lightport
fi

corpus=fuzz/corpus/$target
artifacts=fuzz/artifacts/$target
mkdir -p "$corpus" "$artifacts"
cargo run -q -p lightport-fuzz --bin lightport-fuzz -- seeds "$target" "fuzz/seeds/$target"
max_len=$(cargo run -q -p lightport-fuzz --bin lightport-fuzz -- max-len "$target")
exec "target/$triple/release/$target" "$corpus" "fuzz/seeds/$target" \
    -artifact_prefix="$artifacts/" -max_len="$max_len" -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 "$@"
