#!/usr/bin/env bash
# The C ABI's boundary tests (capi/src/args.rs, capi/src/tests.rs) under Miri, which catches the
# undefined behaviour the boundary exists to prevent (slices of impossible lengths, enum values Rust
# cannot hold, pointer arithmetic that wraps). Miri ships only with nightly toolchains, so this is the
# one check that uses one; where none can be had it prints SKIPPED and the tests ran natively in
# `cargo test --workspace` already.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! timeout 600 rustup component add miri rust-src --toolchain nightly >/dev/null 2>&1; then
    echo "SKIPPED: Miri is not available (rustup component add miri rust-src --toolchain nightly failed):" \
        "the C ABI's boundary tests ran without it"
    exit 0
fi
# Strict provenance: no integer-to-pointer casts anywhere on the paths under test.
MIRIFLAGS="-Zmiri-strict-provenance" cargo +nightly miri test -p nbrdf-capi --lib --target-dir target/miri
echo "Miri check ran: the C ABI's boundary tests under Miri (strict provenance)"
