#!/usr/bin/env bash
# Runs every cargo-fuzz target of fuzz/ for a short, bounded time and fails on the first crash.
#
#   .ci/fuzz.sh                 all targets, FUZZ_SECONDS (default 20) each
#   .ci/fuzz.sh angles          only the named targets
#
# cargo-fuzz needs nightly compiler flags; RUSTC_BOOTSTRAP=1 lets the stable toolchain accept them. Each
# target is built with AddressSanitizer first and, where that build fails (no sanitizer runtime for this
# toolchain or platform), without a sanitizer (`-s none`); the mode that ran is printed. New inputs found
# go to a scratch directory, so the checked-in seed corpora (fuzz/corpus/<target>) stay as they are.
# A crash leaves its input in fuzz/artifacts/<target>/ (see fuzz/README.md to reproduce and minimise).
set -euo pipefail

cd "$(dirname "$0")/.."
seconds="${FUZZ_SECONDS:-20}"
export RUSTC_BOOTSTRAP=1

if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "fuzz: installing cargo-fuzz"
    cargo install cargo-fuzz --locked
fi

if [ "$#" -gt 0 ]; then
    targets=("$@")
else
    mapfile -t targets < <(cargo fuzz list --fuzz-dir fuzz)
fi

scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT

summary=()
for t in "${targets[@]}"; do
    if cargo fuzz build --fuzz-dir fuzz "$t"; then
        mode=(); mode_name="address sanitizer"
    else
        echo "fuzz: $t: sanitizer build failed, falling back to -s none"
        mode=(-s none); mode_name="no sanitizer (-s none)"
        cargo fuzz build --fuzz-dir fuzz "${mode[@]}" "$t"
    fi
    extra=()
    if [ -f "fuzz/dicts/$t.dict" ]; then
        extra+=("-dict=fuzz/dicts/$t.dict")
    fi
    mkdir -p "$scratch/$t"
    echo "fuzz: $t: running ${seconds}s with $mode_name"
    if ! cargo fuzz run --fuzz-dir fuzz "${mode[@]}" "$t" "$scratch/$t" "fuzz/corpus/$t" -- \
        -max_total_time="$seconds" "${extra[@]}"; then
        echo "fuzz: $t: FAILED ($mode_name); the crashing input is in fuzz/artifacts/$t/" >&2
        exit 1
    fi
    summary+=("$t: ok, ${seconds}s, $mode_name")
done

echo "fuzz: all targets passed"
printf '  %s\n' "${summary[@]}"
