"""Type stubs of nbrdf._nbrdf, the Rust extension module (python/src/). Array arguments are any
array-like of real numbers (read in place where they are aligned float32 or float64 arrays, else
converted to float32 once) whose leading dimensions broadcast by numpy's rules; results are float32
arrays. Directions, (3,) or (N, 3), are in the local shading frame (+z = normal), wi toward the light,
wo toward the viewer."""

import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union, final, overload

import numpy as np
import numpy.typing as npt

__all__ = [
    "Model",
    "brdf_rmse",
    "builtin",
    "compare",
    "disney",
    "fit",
    "fmbrdf",
    "from_spec",
    "init_model",
    "kernel_level",
    "lambert",
    "merl",
    "mesh",
    "nbrdf_json",
    "parametric_from_raw",
    "phong",
    "render",
    "study",
    "synth",
    "torrance_sparrow",
]

_F32 = npt.NDArray[np.float32]
_Path = Union[str, "os.PathLike[str]"]
# One direction written out: a call with only these gives a scalar density.
_Vec3 = Tuple[float, float, float]

# A PyO3 class without `subclass`: Python cannot derive from it.
@final
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
    def eval(self, wi: npt.ArrayLike, wo: npt.ArrayLike, points: Optional[npt.ArrayLike] = None) -> _F32:
        """f(wi, wo) per pair: (N, 3) for (N, 3) directions, (3,) for single ones (the broadcast
        leading shape, then 3). `points`: for a model with position_len k > 0, one point (shape (k,))
        for every pair or one per pair ((N, k)); None otherwise."""
    # The overloads give a scalar density where the static types show a single direction; a (3,)
    # array also gives one at run time, which its static type cannot show.
    @overload
    def sample(  # type: ignore[overload-overlap]
        self, wo: _Vec3, u: _Vec3, points: Optional[npt.ArrayLike] = None
    ) -> Tuple[_F32, _F32, np.float32]: ...
    @overload
    def sample(self, wo: npt.ArrayLike, u: npt.ArrayLike, points: Optional[npt.ArrayLike] = None) -> Tuple[_F32, _F32, _F32]:
        """Samples wi for each view wo from uniform numbers u (N, 3) in [0, 1) (u[:, :2] the direction,
        u[:, 2] the lobe): (wi (N, 3), weight = f cos / pdf (N, 3), pdf (N,)), or (3,), (3,) and a
        scalar for a single wo and u; rows without a sample are zeros."""
    @overload
    def pdf(self, wi: _Vec3, wo: _Vec3, points: Optional[npt.ArrayLike] = None) -> np.float32: ...  # type: ignore[overload-overlap]
    @overload
    def pdf(self, wi: npt.ArrayLike, wo: npt.ArrayLike, points: Optional[npt.ArrayLike] = None) -> _F32:
        """Density of `sample` at wi for the view wo per unit solid angle: (N,), or a scalar for single
        directions."""
    def position_features(self, triangles: npt.ArrayLike, bary: npt.ArrayLike) -> _F32:
        """An intrinsic model's point inputs at triangles (N, 3) of the fitted mesh (integers) with
        barycentric weights bary (N, 3), the two broadcast: (N, position_len)."""
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
    def albedo_bound(self) -> Optional[_F32]:
        """The albedo table (32, 3) of an energy-bounded model (``fit(..., energy_bound=True)``); None otherwise."""
    @property
    def has_position_table(self) -> bool:
        """Whether the file carries per-vertex intrinsic features (position_features)."""
    @property
    def n_parameters(self) -> int:
        """Stored parameters (network weights, table entries or model parameters)."""
    @property
    def weights(self) -> _F32:
        """The network weights (and per-object parameters) in file order, (n_parameters,)."""
    def with_weights(self, weights: npt.ArrayLike) -> "Model":
        """The same model with other weights (single precision; an energy bound is dropped)."""
    def with_fitted_sampler(self) -> "Model":
        """The same model with its sampling proxies fitted anew to its present weights."""
    def save(self, path: _Path) -> None:
        """Writes the model's .nbrdf file, atomically."""
    def weight_gradient(
        self, wi: npt.ArrayLike, wo: npt.ArrayLike, grad: npt.ArrayLike, points: Optional[npt.ArrayLike] = None
    ) -> _F32:
        """dL/dw, (n_parameters,), for dL/df = grad at each pair, by the trainer's backward pass."""

def merl(path: _Path) -> Model:
    """Loads a MERL .binary table."""
def nbrdf_json(path: _Path) -> Model:
    """Loads an NBRDF-json network (Sztrajman et al. 2021)."""
def builtin(id: str) -> Model:
    """A built-in material: "two-lobe-metal", "clear-coat" or "velvet"."""
def from_spec(spec: str) -> Model:
    """A BRDF from the path tracer's ``--brdf`` syntax: ``lambert:R,G,B``,
    ``phong:KD_R,KD_G,KD_B,KS_R,KS_G,KS_B,N`` (or ``rp:``), ``torrance-sparrow:KD×3,KS×3,ALPHA`` (or
    ``ts:``), ``fmbrdf:RHO×3,KS,ALPHA,BETA,ETA,NORM``, ``disney:BASE×3,SUBSURFACE,METALLIC,SPECULAR,
    SPECULAR_TINT,ROUGHNESS,SHEEN,SHEEN_TINT,CLEARCOAT,CLEARCOAT_GLOSS``, ``raw:KIND:V,...``,
    ``builtin:ID``, ``merl:FILE.binary``, ``json:FILE.json``, ``model:FILE.nbrdf``, or a file whose
    extension says which. Errors (``ValueError``, ``FileNotFoundError``) name the spec and the
    parameter."""
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
def init_model(
    model: str,
    *,
    reciprocity: Optional[str] = None,
    enhanced: bool = False,
    position: Optional[str] = None,
    angle_frequencies: Optional[int] = None,
    direction_layers: Optional[int] = None,
    seed: int = 0,
    median: Optional[float] = None,
) -> Model:
    """A freshly initialised model (fit's variant arguments), sampling the cosine lobe."""
def kernel_level() -> str:
    """The dense-layer kernel level in use: "avx512", "avx2", "neon" or "portable"."""
def mesh(mesh: str) -> Tuple[_F32, _F32, npt.NDArray[np.uint32]]:
    """Vertices (V, 3), unit vertex normals (V, 3) and triangles (T, 3) of a built-in mesh or an
    OBJ/PLY file scaled into the unit sphere."""
def render(
    brdf: Model,
    mesh: str,
    eye: npt.ArrayLike,
    target: npt.ArrayLike,
    up: npt.ArrayLike,
    fov: float,
    width: int,
    height: int,
    lights: npt.ArrayLike,
    env_color: Optional[npt.ArrayLike],
    env: Optional[_Path],
    spp: int,
    max_depth: int,
    seed: int,
    sampling: str,
) -> Tuple[_F32, _F32]:
    """The path tracer (see nbrdf.render): (mean, variance of the mean), both (H, W, 3)."""
def synth(
    out: _Path,
    *,
    mesh: Optional[_Path] = None,
    material: Optional[str] = None,
    size: Optional[int] = None,
    views: Optional[int] = None,
    train_views: Optional[int] = None,
    train_lights: Optional[int] = None,
    test_lights: Optional[int] = None,
    sigma: Optional[float] = None,
    seed: Optional[int] = None,
    fov: Optional[float] = None,
    light_intensity: Optional[float] = None,
    target_median: Optional[float] = None,
    force_shadows: bool = False,
    interreflections: Optional[int] = None,
    quiet: bool = False,
    progress: Optional[Callable[[int, int], None]] = None,
) -> str:
    """`trainer synth`'s typed request from these arguments (unset: its defaults); returns `out`."""
def fit(
    model: str,
    *,
    data: Optional[_Path] = None,
    toy: Optional[int] = None,
    diligent: Optional[_Path] = None,
    object: Optional[str] = None,
    out: Optional[_Path] = None,
    steps: Optional[int] = None,
    batch: Optional[int] = None,
    lr: Optional[float] = None,
    lr_final: Optional[float] = None,
    seed: Optional[int] = None,
    reciprocity: Optional[str] = None,
    enhanced: bool = False,
    position: Optional[str] = None,
    angle_frequencies: Optional[int] = None,
    direction_layers: Optional[int] = None,
    lambda_diffuse: Optional[float] = None,
    lambda_specular: Optional[float] = None,
    checkpoint_every: Optional[int] = None,
    resume: bool = False,
    pixel_stride: Optional[int] = None,
    cache: Optional[_Path] = None,
    energy_bound: bool = False,
    bar: bool = False,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Tuple[str, str]:
    """`trainer fit`'s typed request from these arguments (unset: its defaults); the model file and the
    log as JSON text."""
def study(config: Optional[str], out: str, bar: bool, progress: Optional[Callable[[int, int], None]] = None) -> str:
    """`trainer study` with this config file (None: the default) into `out`; the results as JSON text."""
def compare(
    reference: npt.ArrayLike,
    test: npt.ArrayLike,
    mask: Optional[npt.ArrayLike] = None,
    lpips_weights: Optional[_Path] = None,
) -> Dict[str, Any]:
    """The study's image metrics (see nbrdf.compare)."""
def brdf_rmse(predicted: npt.ArrayLike, reference: npt.ArrayLike, keep: Optional[npt.ArrayLike] = None) -> Tuple[float, int]:
    """RMSE of the cube roots of (N, 3) BRDF values over the rows keep ((N,) booleans) marks, the three
    broadcast: (rmse, rows used)."""
