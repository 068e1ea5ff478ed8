"""Type stubs of nbrdf._nbrdf, the Rust extension module (python/src/). Arrays are float32 numpy
arrays; (N, 3) directions are in the local shading frame (+z = normal), wi toward the light, wo toward
the viewer."""

import os
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_F32 = npt.NDArray[np.float32]
_Path = Union[str, "os.PathLike[str]"]

class Model:
    """A BRDF: a fitted .nbrdf model, a MERL table, an NBRDF-json network, a parametric model or a
    built-in material. Values in 1/sr without the cosine, 0 below the horizon or for non-finite
    directions. Immutable; safe to share between threads."""

    @staticmethod
    def load(path: _Path) -> "Model":
        """Loads a .nbrdf model, an NBRDF-json .json network or a MERL .binary table (by extension).
        FileNotFoundError/OSError where the file cannot be read, ValueError where it is malformed."""
    @staticmethod
    def from_bytes(data: bytes, format: str = "nbrdf") -> "Model":
        """A BRDF from a file's bytes: format "nbrdf", "json" or "binary"."""
    def eval(self, wi: _F32, wo: _F32, points: Optional[_F32] = None) -> _F32:
        """f(wi, wo) per pair, (N, 3). `points`: for a model with position_len k > 0, one point
        (shape (k,)) for every pair or one per pair ((N, k)); None otherwise."""
    def sample(self, wo: _F32, u: _F32, points: Optional[_F32] = None) -> Tuple[_F32, _F32, _F32]:
        """Samples wi for each view wo from uniform numbers u (N, 3) in [0, 1) (u[:, :2] the direction,
        u[:, 2] the lobe): (wi (N, 3), weight = f cos / pdf (N, 3), pdf (N,)); rows without a sample
        are zeros."""
    def pdf(self, wi: _F32, wo: _F32, points: Optional[_F32] = None) -> _F32:
        """Density of `sample` at wi for the view wo per unit solid angle, (N,)."""
    def position_features(self, triangles: npt.NDArray[np.uint32], bary: _F32) -> _F32:
        """An intrinsic model's point inputs at triangles (N, 3) of the fitted mesh with barycentric
        weights bary (N, 3): (N, position_len)."""
    @property
    def is_reciprocal(self) -> bool:
        """f(wi, wo) == f(wo, wi) by construction."""
    @property
    def kind(self) -> str:
        """"model", "merl", "nbrdf-json", "parametric" or "builtin"."""
    @property
    def parametric_kind(self) -> Optional[str]:
        """"lambert", "phong", "torrance-sparrow", "fmbrdf" or "disney" for a parametric BRDF."""
    @property
    def position_len(self) -> int:
        """Values per point input: 0 (the same everywhere), k (intrinsic) or 3 (extrinsic: x, y, z)."""
    @property
    def has_position_table(self) -> bool:
        """Whether the file carries per-vertex intrinsic features (position_features)."""
    @property
    def n_parameters(self) -> int:
        """Stored parameters (network weights, table entries or model parameters)."""

def merl(path: _Path) -> Model:
    """Loads a MERL .binary table."""
def nbrdf_json(path: _Path) -> Model:
    """Loads an NBRDF-json network (Sztrajman et al. 2021)."""
def builtin(id: str) -> Model:
    """A built-in material: "two-lobe-metal", "clear-coat" or "velvet"."""
def lambert(kd: Sequence[float]) -> Model:
    """Lambert with RGB albedo kd in [0, 1]."""
def phong(kd: Sequence[float], ks: Sequence[float], n: float) -> Model:
    """Energy-preserving modified Phong (RP), kd + ks <= 1."""
def torrance_sparrow(kd: Sequence[float], ks: Sequence[float], alpha: float) -> Model:
    """Torrance-Sparrow with Beckmann roughness alpha > 0."""
def fmbrdf(rho: Sequence[float], ks: float, alpha: float, beta: float, eta: float, norm: float) -> Model:
    """The Fresnel microfacet BRDF."""
def disney(
    base_color: Sequence[float],
    subsurface: float = 0.0,
    metallic: float = 0.0,
    specular: float = 0.5,
    specular_tint: float = 0.0,
    roughness: float = 0.5,
    sheen: float = 0.0,
    sheen_tint: float = 0.5,
    clearcoat: float = 0.0,
    clearcoat_gloss: float = 1.0,
) -> Model:
    """Isotropic Disney (Burley 2012); every parameter in [0, 1]."""
def parametric_from_raw(kind: str, raw: Sequence[float], object: Sequence[float] = ...) -> Model:
    """A parametric model from raw network outputs (any finite values)."""
def kernel_level() -> str:
    """The dense-layer kernel level in use: "avx512", "avx2", "neon" or "portable"."""
def mesh(mesh: str) -> Tuple[_F32, _F32, npt.NDArray[np.uint32]]:
    """Vertices (V, 3), unit vertex normals (V, 3) and triangles (T, 3) of a built-in mesh or an
    OBJ/PLY file scaled into the unit sphere."""
def render(
    brdf: Model,
    mesh: str,
    eye: List[float],
    target: List[float],
    up: List[float],
    fov: float,
    width: int,
    height: int,
    lights: List[Tuple[List[float], List[float]]],
    env_color: Optional[List[float]],
    env: Optional[str],
    spp: int,
    max_depth: int,
    seed: int,
    sampling: str,
) -> Tuple[_F32, _F32]:
    """The path tracer (see nbrdf.render): (mean, variance of the mean), both (H, W, 3)."""
def synth(argv: List[str]) -> str:
    """`trainer synth` with these flags; returns the output folder."""
def fit(argv: List[str], progress: bool) -> Tuple[str, str]:
    """`trainer fit` with these flags; returns the model file and the log as JSON text."""
def compare(
    reference: _F32, test: _F32, mask: Optional[npt.NDArray[np.bool_]], lpips_weights: Optional[str]
) -> dict:
    """The study's image metrics (see nbrdf.compare)."""
def brdf_rmse(predicted: _F32, reference: _F32, keep: Optional[Sequence[bool]] = None) -> Tuple[float, int]:
    """RMSE of the cube roots of (N, 3) BRDF values over the rows keep marks: (rmse, rows used)."""
