"""nbrdf: neural BRDFs from Python (On Neural BRDFs: A Thorough Comparison of State-of-the-Art
Approaches), over numpy arrays.

- ``Model``: one class for every BRDF (``Model.load`` a ``.nbrdf`` model, an NBRDF-json network or a
  MERL table; ``merl``, ``nbrdf_json``, ``lambert``, ``phong``, ``torrance_sparrow``, ``fmbrdf``,
  ``disney``, ``builtin``, ``from_spec``) with ``eval``, ``sample`` and ``pdf`` over directions, (3,) or
  (N, 3).
- ``render`` and ``mesh``: nbrdf's own path tracer and the meshes it draws.
- ``synth``, ``fit``, ``compare``, ``brdf_rmse``: the trainer's data sets, fitting and metrics.
- ``nbrdf.mitsuba``: a Mitsuba 3 BSDF plugin, ``"nbrdf"``.

Conventions: local shading frame with the normal on +z; ``wi`` points toward the light and ``wo``
toward the viewer, both away from the surface; values in 1/sr without the cosine; 0 below the horizon
and for non-finite directions. Every call releases the GIL and spreads large batches over all cores.

Arrays follow numpy's conventions. An array argument is any array-like of real numbers (any dtype
from bool and integers to float64, lists, tuples, numpy scalars, views of any strides); the leading
dimensions of a call's arguments broadcast by numpy's rules (``wi`` (N, 3) with ``wo`` (3,) or (1, 3);
a single (3,) query gives a (3,) value and a scalar density); results are float32 with the broadcast
leading shape. The cost: every input is read once into the call's own buffer (so that the work runs
without the GIL); aligned float32 and float64 arrays are read in place, float64 rounded as
``astype(np.float32)`` rounds, so its results equal the float32 call's bit for bit; anything else is
converted to float32 once. Strings, objects, complex numbers and shapes that do not broadcast raise
ValueError or TypeError naming the argument.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Callable, Dict, List, NamedTuple, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _nbrdf
from ._nbrdf import (
    Model,
    brdf_rmse,
    builtin,
    disney,
    fmbrdf,
    from_spec,
    init_model,
    kernel_level,
    lambert,
    merl,
    mesh,
    nbrdf_json,
    parametric_from_raw,
    phong,
    torrance_sparrow,
)

__all__ = [
    "Model",
    "FitResult",
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

PathLike = Union[str, "os.PathLike[str]"]


ProgressCallback = Callable[[int, int], None]
Progress = Union[None, bool, ProgressCallback]


def _in_notebook() -> bool:
    """Whether this runs in a Jupyter kernel, whose output shows a display but no terminal bar."""
    shell = sys.modules.get("IPython")
    get = getattr(shell, "get_ipython", None) if shell is not None else None
    ip = get() if get is not None else None
    return ip is not None and "IPKernelApp" in getattr(ip, "config", {})


class _NotebookBar:
    """A progress display in a notebook cell: tqdm's notebook bar where tqdm is installed, else one
    line of text updated in place."""

    def __init__(self, what: str) -> None:
        self._what = what
        self._bar: Any = None
        self._handle: Any = None
        # Imported by name: both are optional and untyped, and only a notebook has them.
        import importlib

        try:
            self._bar = importlib.import_module("tqdm.auto").tqdm(desc=what, total=0)
        except ImportError:
            display = importlib.import_module("IPython.display").display
            self._handle = display(f"{what}: starting", display_id=True)

    def __call__(self, done: int, total: int) -> None:
        if self._bar is not None:
            self._bar.total = total
            self._bar.n = done
            self._bar.refresh()
        elif self._handle is not None:
            self._handle.update(f"{self._what}: {done}/{total}")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _progress(progress: Progress, what: str) -> Tuple[bool, Optional[ProgressCallback], Callable[[], None]]:
    """What ``progress`` asks for: (the trainer's terminal bar, a callable fed ``(done, total)``, what
    closes the display). ``None``: a bar where stderr is a terminal, a display in a notebook, else
    nothing; ``True``/``False``: the terminal bar or nothing; a callable: called, no bar."""
    if callable(progress):
        return False, progress, lambda: None
    if progress is None and _in_notebook():
        bar = _NotebookBar(what)
        return False, bar, bar.close
    return (_interactive() if progress is None else bool(progress)), None, lambda: None


def _interactive() -> bool:
    """Whether a progress bar helps: stderr is a terminal (not a pipe, a file or a notebook)."""
    try:
        return sys.stderr is not None and sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def render(
    brdf: Model,
    *,
    mesh: PathLike = "sphere",
    eye: npt.ArrayLike = (0.0, 0.6, 3.4),
    target: npt.ArrayLike = (0.0, 0.0, 0.0),
    up: npt.ArrayLike = (0.0, 1.0, 0.0),
    fov: float = 40.0,
    width: int = 128,
    height: int = 128,
    lights: npt.ArrayLike = (),
    env_color: Optional[npt.ArrayLike] = None,
    env: Optional[PathLike] = None,
    spp: int = 16,
    max_depth: int = 8,
    seed: int = 0,
    sampling: str = "native",
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """Path-traces ``mesh`` ("sphere", "torus", "grooved" or an OBJ/PLY file, scaled into the unit
    sphere) with ``brdf``, as ``cargo run -p nbrdf-scene --example path_tracer`` does: a pinhole camera
    at ``eye`` looking at ``target`` (vertical field of view ``fov`` degrees), directional ``lights`` given as
    ``(direction toward the light, RGB intensity)`` pairs (a list of pairs or an (L, 2, 3) array), and a constant environment ``env_color`` or a
    lat-long OpenEXR map ``env`` (+y up). ``sampling`` is "native" (the BRDF's lobes or fitted proxy) or
    "cosine". Returns the mean radiance per pixel and the variance of that mean, both
    (height, width, 3) float32; rows run top to bottom."""
    return _nbrdf.render(
        brdf,
        os.fspath(mesh),
        eye,
        target,
        up,
        float(fov),
        width,
        height,
        lights,
        env_color,
        None if env is None else os.fspath(env),
        spp,
        max_depth,
        seed,
        sampling,
    )


def synth(
    out: PathLike,
    *,
    mesh: PathLike = "sphere",
    material: str = "two-lobe-metal",
    size: int = 256,
    views: int = 20,
    train_views: int = 10,
    train_lights: int = 30,
    test_lights: int = 12,
    sigma: float = 1e-3,
    seed: int = 0,
    fov: float = 40.0,
    light_intensity: Optional[float] = None,
    target_median: Optional[float] = None,
    force_shadows: bool = False,
    interreflections: int = 0,
    progress: Progress = None,
) -> Path:
    """Renders a semi-synthetic data set (Sec. 5.3; ``trainer synth``): ``mesh`` ("sphere", "torus",
    "grooved" or an OBJ/PLY file) with the ground-truth ``material`` (a built-in id, a MERL ``.binary``,
    an NBRDF-json ``.json`` or ``lambert:R,G,B``), seen from ``views`` cameras, each lit by directional
    lights, with Gaussian noise ``sigma``; the lights have ``light_intensity`` (default 1), or the one
    that exposes the object's lit pixels at median luminance ``target_median`` (docs/study.md).
    ``interreflections``: also the light that bounces between the object's parts, path traced with this
    many samples per pixel per image (0, the paper's data: direct light only); each image's
    interreflected part is written beside it. Writes ``out/dataset.json`` with its images and returns
    ``out``. ``progress``: by default a bar where stderr is a terminal, a display in a Jupyter
    notebook, nothing elsewhere; ``True``/``False`` force the terminal bar on or off; a callable is
    called with ``(images written, images)``. Ctrl-C (a notebook's interrupt) stops it within a
    second, leaving ``out`` as it was."""
    bar, callback, close = _progress(progress, "synth")
    try:
        return Path(_nbrdf.synth(
            out, mesh=mesh, material=material, size=size, views=views, train_views=train_views,
            train_lights=train_lights, test_lights=test_lights, sigma=sigma, seed=seed, fov=fov,
            light_intensity=light_intensity, target_median=target_median, force_shadows=force_shadows,
            interreflections=interreflections, quiet=not bar, progress=callback,
        ))
    finally:
        close()


class FitResult(NamedTuple):
    """What ``fit`` returns: the fitted model file and the training log (``<name>.log.json``)."""

    model: Path
    log: Dict[str, Any]

    def load(self) -> Model:
        """The fitted model, loaded (``Model.load(self.model)``)."""
        return Model.load(self.model)

    @property
    def curve(self) -> Dict[str, npt.NDArray[np.float64]]:
        """The learning curve as arrays of equal length: ``step``, ``wall_s`` (training time, probes
        excluded), ``train_loss`` and ``test_psnr`` (NaN where a point has none)."""
        points = self.log.get("curve", [])

        def column(key: str) -> npt.NDArray[np.float64]:
            return np.array([np.nan if p.get(key) is None else p[key] for p in points], dtype=np.float64)

        return {key: column(key) for key in ("step", "wall_s", "train_loss", "test_psnr")}


def fit(
    model: str,
    *,
    data: Optional[PathLike] = None,
    toy: Optional[int] = None,
    diligent: Optional[PathLike] = None,
    object: Optional[str] = None,
    out: Optional[PathLike] = None,
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
    cache: Optional[PathLike] = None,
    energy_bound: bool = False,
    progress: Progress = None,
) -> FitResult:
    """Fits one model variant (Sec. 4.1; ``trainer fit``) and writes ``<variant>.nbrdf``, a checkpoint
    and a JSON log into ``out``. ``model`` is rp, ts, fmbrdf, disney, lambert, single-mlp,
    additive-separate or additive-shared; the data is a ``synth`` folder (``data``), a DiLiGenT-MV copy
    (``diligent`` and ``object``) or the analytic toy set of ``toy`` pixels. ``position`` is uniform,
    intrinsic:K or extrinsic:F. Unset options take ``trainer fit``'s defaults: ``object`` bear, ``out``
    "out", 20 000 ``steps``, ``batch`` the paper's 2^15 colour values, ``lr`` 1e-3 to ``lr_final`` 1e-4,
    ``seed`` 0, ``reciprocity`` exact, ``position`` intrinsic:32, a checkpoint every 1000 steps, every
    pixel (``pixel_stride`` 1), ``cache`` "out/cache". ``energy_bound``: write the model with its albedo
    bound (``trainer fit --energy-bound``; albedo at most 1 at every view, docs/models.md). ``progress``: as ``synth``'s, the callable called with ``(steps done, steps)``.
    Ctrl-C (a notebook's interrupt) stops it within a second, leaving ``out`` as it was. Returns the
    model file and the log (``FitResult``: ``load()`` the model, ``curve`` as arrays)."""
    import json

    bar, callback, close = _progress(progress, model)
    try:
        path, log = _nbrdf.fit(
            model, data=data, toy=toy, diligent=diligent, object=object, out=out, steps=steps, batch=batch,
            lr=lr, lr_final=lr_final, seed=seed, reciprocity=reciprocity, enhanced=enhanced,
            position=position, angle_frequencies=angle_frequencies, direction_layers=direction_layers,
            lambda_diffuse=lambda_diffuse, lambda_specular=lambda_specular,
            checkpoint_every=checkpoint_every, resume=resume, pixel_stride=pixel_stride, cache=cache,
            energy_bound=energy_bound, bar=bar, progress=callback,
        )
    finally:
        close()
    return FitResult(Path(path), json.loads(log))


def study(
    config: Optional[PathLike] = None,
    *,
    out: PathLike = "out/study",
    progress: Progress = None,
) -> List[Dict[str, Any]]:
    """Runs the comparison study (Sec. 6; ``trainer study``): the JSON ``config`` file (see
    docs/study.md; ``None``: the embedded default, two built-in objects and the Tabs. 1-3 variants),
    writing ``out/REPORT.md`` with its figures and ``results.json``. Returns every job's result as a
    dict (``scene``, ``model``, ``eval`` with the image metrics against the clean reference,
    ``curve``, ...). ``progress``: as ``fit``'s, for each fit in turn. Ctrl-C (a notebook's
    interrupt) stops it at its next training step or job (an evaluation under way finishes first);
    finished jobs are kept and the next run reuses them."""
    import json

    bar, callback, close = _progress(progress, "study")
    try:
        text = _nbrdf.study(None if config is None else os.fspath(config), os.fspath(out), bar, callback)
    finally:
        close()
    results: List[Dict[str, Any]] = json.loads(text)
    return results


def compare(
    reference: npt.ArrayLike,
    test: npt.ArrayLike,
    mask: Optional[npt.ArrayLike] = None,
    *,
    lpips_weights: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """The study's image metrics (Sec. 6, Tab. 1) of a **linear** RGB rendering ``test`` against
    ``reference``, both (H, W, 3) (any real dtype; read as float32), over the object pixels ``mask`` ((H, W) bool) where given:
    ``psnr`` (dB on sRGB, inf when equal), ``dssim``, ``lpips`` (AlexNet v0.1; None where its weights
    are missing, the reason in ``lpips_na``) and ``flip`` (mean HDR-FLIP). The LPIPS weights are read
    from ``lpips_weights``, else ``$NBRDF_DATA/lpips/alexnet-lpips-v0.1.safetensors``."""
    return _nbrdf.compare(reference, test, mask, None if lpips_weights is None else os.fspath(lpips_weights))
