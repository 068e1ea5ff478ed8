"""Shared fixtures of the Python package's tests: fitted models made once per session with
``nbrdf.fit`` (the trainer's toy set, 50 steps: seconds), the repository's shared data, and the Rust
API's reference values."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import nbrdf

REPO = Path(__file__).resolve().parents[2]


def data_dir() -> Path:
    """``$NBRDF_DATA``, else ``../shared/data`` beside the repository (the project's convention)."""
    return Path(os.environ.get("NBRDF_DATA", REPO.parent / "shared" / "data"))


def nbrdf_json_files() -> list:
    d = data_dir() / "nbrdf-merl"
    return sorted(d.glob("*.json")) if d.is_dir() else []


def need_json(name: str = "gold-metallic-paint") -> Path:
    path = data_dir() / "nbrdf-merl" / f"{name}.json"
    if not path.is_file():
        pytest.skip(f"{path} not found (set NBRDF_DATA to the shared data folder)")
    return path


@pytest.fixture(scope="session")
def fitted(tmp_path_factory) -> Path:
    """A Single MLP fitted for 50 steps to the toy set, uniform over the surface."""
    out = tmp_path_factory.mktemp("fit-uniform")
    result = nbrdf.fit("single-mlp", toy=2000, position="uniform", steps=50, out=out, progress=False)
    return result.model


@pytest.fixture(scope="session")
def fitted_extrinsic(tmp_path_factory) -> Path:
    """An Additive Separate model fitted for 20 steps, extrinsically encoded (its point input is x, y, z)."""
    out = tmp_path_factory.mktemp("fit-extrinsic")
    result = nbrdf.fit("additive-separate", toy=1000, position="extrinsic:2", steps=20, out=out, progress=False)
    return result.model


def unit_rows(rng: np.random.Generator, n: int, upper: bool = True) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    if upper:
        v[:, 2] = np.abs(v[:, 2])
    return (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)


@pytest.fixture(scope="session")
def reference_values(tmp_path_factory, fitted, fitted_extrinsic):
    """Runs the Rust API over deterministic inputs (examples/reference_values.rs) for a set of BRDFs
    and returns [(spec, arrays)]; skipped where cargo is not installed (a wheel without the source)."""
    cargo = shutil.which("cargo")
    if cargo is None or not (REPO / "examples" / "reference_values.rs").is_file():
        pytest.skip("cargo or the repository's examples/reference_values.rs not found")
    specs = [
        f"model:{fitted}",
        f"model:{fitted_extrinsic}",
        "lambert:0.8,0.5,0.2",
        "phong:0.3,0.2,0.1,0.5,0.5,0.5,40",
        "torrance-sparrow:0.2,0.3,0.4,0.5,0.4,0.3,0.25",
        "fmbrdf:0.4,0.3,0.2,0.6,0.3,0.8,1.5,1.2",
        "disney:0.8,0.4,0.2,0.1,0.3,0.5,0.2,0.4,0.3,0.5,0.6,0.7",
        "builtin:velvet",
        "builtin:two-lobe-metal",
    ]
    json = nbrdf_json_files()
    if json:
        specs.append(f"json:{json[0]}")
    n = 3000  # above the package's parallel chunk (1024), so the split across threads is covered
    out = tmp_path_factory.mktemp("reference") / "values.bin"
    # The test profile: the build `cargo test --workspace` (and CI) already made.
    cmd = [cargo, "run", "--quiet", "--profile", os.environ.get("NBRDF_REFERENCE_PROFILE", "test"),
           "--example", "reference_values", "--", str(out), str(n), *specs]
    subprocess.run(cmd, cwd=REPO, check=True)
    raw = out.read_bytes()
    at = 4
    assert int.from_bytes(raw[:4], "little") == n

    def take(count: int) -> np.ndarray:
        nonlocal at
        a = np.frombuffer(raw, dtype="<f4", count=count, offset=at)
        at += 4 * count
        return a

    result = []
    for spec in specs:
        k = int.from_bytes(raw[at:at + 4], "little")
        at += 4
        arrays = {"k": k}
        for name, width in [("wi", 3), ("wo", 3), ("u", 3), ("points", k), ("eval", 3), ("pdf", 1),
                            ("sample_wi", 3), ("sample_weight", 3), ("sample_pdf", 1), ("eval_at_point0", 3)]:
            a = take(n * width)
            arrays[name] = a.reshape(n, width) if width != 1 else a
        result.append((spec, arrays))
    assert at == len(raw)
    return result
