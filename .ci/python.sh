#!/usr/bin/env bash
# The Python package (python/): makes a virtual environment, installs maturin, pytest, numpy, mypy and
# Mitsuba 3 from PyPI, builds the extension with maturin, installs the wheel, checks its type stubs
# against it and runs python/tests.
# Only where PyPI cannot be reached does it print SKIPPED with the reason and exit 0.
set -euo pipefail
cd "$(dirname "$0")/.."

venv="${NBRDF_VENV:-.venv}"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
py="$(cd "$venv" && pwd)/bin/python"
# Already-installed packages need no network, so a rerun works offline.
if ! "$py" -m pip install -q maturin pytest numpy mypy mitsuba nbconvert ipykernel; then
    if ! "$py" -m pip download -q --no-deps -d "$(mktemp -d)" pip >/dev/null 2>&1; then
        echo "SKIPPED: PyPI cannot be reached: the Python package was not built or tested"
        exit 0
    fi
    echo "pip could not install maturin, pytest, numpy, mypy, mitsuba, nbconvert and ipykernel although PyPI answers" >&2
    exit 1
fi

# Mitsuba's LLVM variants need libLLVM 16 or newer (Dr.Jit refuses 14; 15 aborted in its AVX-512 code
# generation): install one where apt can, else the tests of those variants skip with the reason.
have_llvm16() {
    for f in /usr/lib/*/libLLVM-1[6-9]*.so* /usr/lib/*/libLLVM-[2-9][0-9]*.so*; do [ -e "$f" ] && return 0; done
    return 1
}
if ! have_llvm16 && command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null 2>&1 \
        || { apt-get update -qq >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null 2>&1; } \
        || echo "note: libllvm19 could not be installed; the llvm_ad_rgb tests will say why they skip"
fi

# The dev profile with the test profile's settings (opt-level 2, no LTO, line tables): the Mitsuba
# and chi-square tests evaluate millions of queries, too slow unoptimised, and the release profile's
# opt-level 3 and debug info cost a clean CI build minutes more. (`maturin --profile test` would make a
# test harness.) `pip install ./python`, the README's command, builds the release profile instead.
export CARGO_PROFILE_DEV_OPT_LEVEL=2 CARGO_PROFILE_DEV_LTO=off CARGO_PROFILE_DEV_DEBUG=line-tables-only
rm -rf target/wheels
"$venv/bin/maturin" build --profile dev -m python/Cargo.toml -o target/wheels 2>&1 \
    | grep -vE '^\s+(Compiling|Downloaded|Downloading)'
"$py" -m pip install -q --force-reinstall --no-deps target/wheels/nbrdf-*.whl

# The stubs match the installed module (stubtest imports it, from /tmp where no source folder shadows
# it; the allowlist says what is dynamic), and the package and a typed example pass mypy --strict.
allowlist="$PWD/python/stubtest-allowlist.txt"
(cd /tmp && "$py" -m mypy.stubtest nbrdf --allowlist "$allowlist")
"$py" -m mypy --strict --cache-dir target/mypy-cache python/nbrdf/__init__.py python/nbrdf/_nbrdf.pyi python/examples/typed_usage.py
"$py" python/examples/typed_usage.py >/dev/null

# From the repository root, not python/, whose nbrdf/ sources (without the extension) would shadow
# the installed package. The tests run the Rust API's reference values through cargo in the same
# profile.
NBRDF_REFERENCE_PROFILE=dev "$py" -m pytest -q -p no:cacheprovider python/tests

# The weight gradients again at the kernel levels below this CPU's: the forward values they are
# checked against are the core's, which switch by level (NBRDF_KERNEL), as in .ci/run.
case "$("$py" -c 'import nbrdf; print(nbrdf.kernel_level())')" in
    avx512) lower="avx2 portable" ;;
    avx2 | neon) lower="portable" ;;
    *) lower="" ;;
esac
for level in $lower; do
    echo "== the gradient tests at NBRDF_KERNEL=$level"
    NBRDF_KERNEL=$level "$py" -m pytest -q -p no:cacheprovider python/tests -k "gradient or differentiable"
done

# The quickstart notebook, executed headless in a Jupyter kernel of this environment (outside the
# source folder, as above); a failing cell fails CI.
"$py" -m ipykernel install --user --name nbrdf-ci >/dev/null
(cd /tmp && "$py" -m jupyter nbconvert --to notebook --execute --ExecutePreprocessor.kernel_name=nbrdf-ci \
    --ExecutePreprocessor.timeout=300 --output-dir "$(mktemp -d)" "$OLDPWD/python/examples/quickstart.ipynb")
echo "quickstart notebook ran: python/examples/quickstart.ipynb"
