#!/usr/bin/env bash
# The core's library and kernel tests built for aarch64 and run under qemu user emulation, once at the
# NEON level and once forced to the portable one: the ARM paths (Apple, Graviton) that an x86 host
# would otherwise never run. Installs what it needs where it can (rustup target, Debian's cross gcc
# and qemu-user-static); where it cannot, it says it skipped and why, and exits 0.
set -uo pipefail
cd "$(dirname "$0")/.."

skip() {
    echo "aarch64 check SKIPPED: $*"
    exit 0
}

if [ "$(uname -m)" = aarch64 ]; then
    skip "this host is aarch64: the suites above ran its NEON level natively"
fi
rustup target add aarch64-unknown-linux-gnu >/dev/null 2>&1 || skip "rustup cannot add aarch64-unknown-linux-gnu"
if ! command -v aarch64-linux-gnu-gcc >/dev/null || ! command -v qemu-aarch64-static >/dev/null; then
    if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
        echo "installing gcc-aarch64-linux-gnu, libc6-dev-arm64-cross and qemu-user-static"
        (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user-static) >/dev/null 2>&1 \
            || skip "apt-get could not install the cross compiler and qemu"
    else
        skip "no aarch64 cross gcc or qemu-aarch64-static, and no apt-get as root to install them"
    fi
fi

export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64-static -L /usr/aarch64-linux-gnu"
export CC_aarch64_unknown_linux_gnu=aarch64-linux-gnu-gcc
set -e
# The library's unit tests (every kernel against its f64 reference, packets against single queries)
# and the integration tests of the kernels and the model file.
tests=(--lib --test kernels --test model_file --test angles)
cargo test -p nbrdf --target aarch64-unknown-linux-gnu "${tests[@]}"
NBRDF_KERNEL=portable cargo test -p nbrdf --target aarch64-unknown-linux-gnu "${tests[@]}"
# The lane types both the core and the trainer are written over, NEON's included.
cargo test -p nbrdf-lanes --target aarch64-unknown-linux-gnu --lib
echo "aarch64 check ran: the core's tests at the neon and portable levels under qemu"
