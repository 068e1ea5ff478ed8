"""The package as typed code uses it, checked by ``mypy --strict`` in CI (.ci/python.sh) against the
stubs, and run there too: float64 and list inputs, a single query and a batch, broadcasting."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

import nbrdf


def shade(m: nbrdf.Model, lights: npt.NDArray[np.float64], view: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Cosine-weighted values of many lights (N, 3) seen from one view (3,)."""
    f = m.eval(lights, view)
    cos: npt.NDArray[np.float32] = np.clip(lights[:, 2], 0.0, None).astype(np.float32)
    return f * cos[:, None]


def main() -> None:
    m = nbrdf.builtin("two-lobe-metal")
    wi = np.array([0.3, 0.1, 0.95]) / np.linalg.norm([0.3, 0.1, 0.95])  # float64, numpy's default
    wo = [0.0, 0.3, 0.954]
    rgb: npt.NDArray[np.float32] = m.eval(wi, wo)
    single: np.float32 = m.pdf((0.0, 0.0, 1.0), (0.0, 0.6, 0.8))
    lights = np.random.default_rng(0).normal(size=(100, 3))
    lights[:, 2] = np.abs(lights[:, 2])
    lights /= np.linalg.norm(lights, axis=1, keepdims=True)
    shaded = shade(m, lights, wo)
    wi_s, weight, pdf = m.sample(np.tile(wo, (100, 1)), np.random.default_rng(1).random((100, 3)))
    kept: npt.NDArray[np.float32] = pdf[pdf > 0]
    print(rgb.shape, float(single), shaded.shape, wi_s.shape, weight.dtype, kept.size)


if __name__ == "__main__":
    main()
