"""Fits an nbrdf model to posed HDR images inside Mitsuba 3, with global illumination.

The trainer fits Eq. 9 of the paper: direct light with cast shadows, pixel by pixel. Light that bounces
between parts of the object (in grooves, recesses, under a handle) is in the captured images but not in
that model of them, so a direct-only fit explains it as a brighter BRDF. Here the model is optimised
through Mitsuba's path replay integrator (``prb``), which renders every bounce: the nbrdf BSDF's
``differentiable`` mode hands each bounce's ``∂L/∂f`` to the trainer's own backward pass.

Usage (a data set written by ``trainer synth`` or ``nbrdf.synth``; its images, cameras, lights and mesh):

    python fit_in_mitsuba.py DATA --init fit/model.nbrdf --out gi.nbrdf     # fine-tune a trainer fit
    python fit_in_mitsuba.py DATA --model additive-separate --out gi.nbrdf  # or start from scratch

``--init`` takes any ``.nbrdf`` model the trainer writes (an energy bound is dropped: it belonged to the
old weights). The result is an ordinary ``.nbrdf`` file (sampling proxies refitted to the new weights)
that the core, C, the shaders and the path tracer load like any other. Needs Mitsuba 3 with an
``*_ad_rgb`` variant (``llvm_ad_rgb`` on a CPU with libLLVM 16+, ``cuda_ad_rgb`` on an NVIDIA GPU).

The module's functions (``Dataset``, ``scene_dict``, ``fit``, ``render_views``) are reused by
``interreflections_study.py``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

import nbrdf


def srgb(x: np.ndarray) -> np.ndarray:
    """The trainer's tone curve γ of Eq. 10 (sRGB of the input clamped to [0, 1])."""
    c = np.clip(x, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.maximum(c, 0.0031308) ** (1 / 2.4) - 0.055)


def srgb_slope(x: np.ndarray) -> np.ndarray:
    """γ's derivative (zero above 1, where γ clips)."""
    c = np.asarray(x, dtype=np.float64)
    slope = np.where(c <= 0.0031308, 12.92, 1.055 / 2.4 * np.maximum(c, 0.0031308) ** (1 / 2.4 - 1))
    return np.where(c < 1.0, slope, 0.0).astype(np.float32)


class Dataset:
    """A data set folder of ``trainer synth``: its views (cameras in the OpenCV convention), images and
    lights, read from ``dataset.json``."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.spec = json.loads((self.folder / "dataset.json").read_text())
        self.width, self.height = self.spec["width"], self.spec["height"]
        mesh = self.spec["mesh"]
        self.mesh = mesh["id"] if mesh["kind"] == "builtin" else mesh["path"]
        self.views = self.spec["views"]

    def split(self, which: str) -> List[int]:
        return [i for i, v in enumerate(self.views) if v["split"] == which]

    def image(self, view: int, light: int, key: str = "radiance") -> np.ndarray:
        import mitsuba as mi

        rel = self.views[view]["images"][light][key]
        return np.asarray(mi.Bitmap(str(self.folder / rel)), dtype=np.float32)[..., :3]

    def mask(self, view: int, erode: int = 1) -> np.ndarray:
        """The view's object pixels, less `erode` pixels along the silhouette (where a pixel's area
        straddles the object, which Mitsuba's pixel filter and the data set's one ray per pixel see
        differently), as (height, width) bool."""
        import mitsuba as mi

        m = np.asarray(mi.Bitmap(str(self.folder / self.views[view]["mask"])))
        m = (m.reshape(self.height, self.width, -1)[..., 0] > 127)
        for _ in range(erode):
            p = np.pad(m, 1)
            m = m & p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
        return m

    def light(self, view: int, light: int) -> Tuple[np.ndarray, np.ndarray]:
        """(direction toward the light, RGB intensity) of an image."""
        spec = self.views[view]["images"][light]["light"]
        return np.float64(spec["direction"]), np.float64(spec["intensity"])

    def sensor(self, view: int, spp: int) -> Dict[str, Any]:
        """A Mitsuba perspective sensor at the view's camera: OpenCV's camera axes (x right, y down,
        z forward) are Mitsuba's (x left, y up, z forward) turned half a turn about z."""
        import mitsuba as mi

        v = self.views[view]
        k, r, t = np.float64(v["K"]), np.float64(v["R"]), np.float64(v["t"])
        to_world = np.eye(4)
        to_world[:3, :3] = r.T @ np.diag([-1.0, -1.0, 1.0])
        to_world[:3, 3] = -r.T @ t
        fov = np.degrees(2 * np.arctan(0.5 * self.height / k[1, 1]))
        return {
            "type": "perspective",
            "fov": float(fov),
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f(to_world.tolist()),
            "film": {"type": "hdrfilm", "width": self.width, "height": self.height, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        }


def scene_dict(ds: Dataset, bsdf: Dict[str, Any], view: int, light: int, integrator: Dict[str, Any],
               spp: int, ply: Path) -> Dict[str, Any]:
    """The scene of one image: the mesh (in the data set's unit-sphere frame) with `bsdf`, the view's
    camera and the image's directional light (irradiance = the light's intensity, as in Eq. 9)."""
    import mitsuba as mi
    import nbrdf.mitsuba

    direction, intensity = ds.light(view, light)
    return {
        "type": "scene",
        "integrator": integrator,
        "sensor": ds.sensor(view, spp),
        "object": nbrdf.mitsuba.shape(ds.mesh, str(ply), bsdf),
        "light": {"type": "directional", "direction": (-direction).tolist(),
                  "irradiance": {"type": "rgb", "value": intensity.tolist()}},
    }


def light_transform(direction: np.ndarray) -> Any:
    """The directional emitter's `to_world` for light arriving from `direction` (its +z is the
    direction the light travels)."""
    import mitsuba as mi

    return mi.Transform4f().look_at(origin=[0, 0, 0], target=(-direction).tolist(),
                                    up=[0, 0, 1] if abs(direction[2]) < 0.9 else [1, 0, 0])


class _PixelCentre:
    """A sampler stand-in whose first 2D sample (a camera ray's place in its pixel) is the pixel's centre;
    every other sample comes from the wrapped sampler, whose dimension it still advances."""

    def __init__(self, sampler: Any) -> None:
        self._sampler, self._first = sampler, True

    def sample_count(self) -> int:
        return self._sampler.sample_count()

    def next_1d(self, *args: Any) -> Any:
        return self._sampler.next_1d(*args)

    def next_2d(self, *args: Any) -> Any:
        sample = self._sampler.next_2d(*args)
        if self._first:
            import mitsuba as mi

            self._first = False
            return mi.Point2f(0.5, 0.5)
        return sample


def register_pixel_centre_prb() -> str:
    """Registers ``prb_pixel_centre``: Mitsuba's ``prb`` with every camera ray through its pixel's centre.

    A data set's images sample each pixel at its centre (one ray per pixel, the trainer's model of them);
    Mitsuba's cameras average the pixel's area. The two differ along silhouettes, creases and shadow
    edges by far more than the models differ (27.7 dB PSNR between the ground-truth material rendered
    each way on the rocker arm), and a fit against the centre samples through area-averaged renders
    bends the BRDF to explain those edges. Rendering the same rays removes the mismatch."""
    import mitsuba as mi
    from mitsuba.ad.integrators.prb import PRBIntegrator

    class PixelCentrePRB(PRBIntegrator):
        def sample_rays(self, scene: Any, sensor: Any, sampler: Any) -> Any:
            return super().sample_rays(scene, sensor, _PixelCentre(sampler))

    mi.register_integrator("prb_pixel_centre", lambda props: PixelCentrePRB(props))
    return "prb_pixel_centre"


def fit(ds: Dataset, start: "nbrdf.Model", work: Path, iterations: int, spp: int = 8, max_depth: int = 4,
        lr: float = 1e-4, seed: int = 0, log_every: int = 10) -> Tuple["nbrdf.Model", Dict[str, Any]]:
    """Optimises `start`'s weights with Adam through Mitsuba's ``prb`` integrator: each iteration renders
    one training image (views and lights in a shuffled cycle) through each pixel's centre, as the data
    set's images were, and steps on Eq. 10's tone-mapped MSE (to first order) over the object's pixels
    inside its silhouette. Returns the fitted model and a log (loss and seconds per iteration)."""
    import drjit as dr
    import mitsuba as mi
    import nbrdf.mitsuba

    work.mkdir(parents=True, exist_ok=True)
    # The differentiable plugin refuses an energy-bounded model; its unbounded twin is the start.
    start_file = work / "start.nbrdf"
    start.with_weights(start.weights).save(start_file)
    bsdf = {"type": "nbrdf", "filename": str(start_file), "differentiable": True}
    integrator = {"type": register_pixel_centre_prb(), "max_depth": max_depth}
    train = [(v, li) for v in ds.split("train") for li in range(len(ds.views[v]["images"]))]
    # One scene per training view (its sensor); the light is moved per image.
    scenes = {v: mi.load_dict(scene_dict(ds, bsdf, v, 0, integrator, spp, work / "mesh.ply")) for v, _ in train}
    params = {v: mi.traverse(s) for v, s in scenes.items()}
    key = "object.bsdf.weights"
    opt = mi.ad.Adam(lr=lr)
    opt[key] = params[train[0][0]][key]
    log: Dict[str, List[float]] = {"iteration": [], "loss": [], "seconds": []}
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(train))
    targets: Dict[Tuple[int, int], Any] = {}
    for it in range(iterations):
        view, light = train[order[it % len(train)]]
        p = params[view]
        p[key] = opt[key]
        p["light.to_world"] = light_transform(ds.light(view, light)[0])
        p.update()
        if (view, light) not in targets:
            image = ds.image(view, light)
            inside = ds.mask(view)[..., None].astype(np.float32)
            targets[(view, light)] = (mi.TensorXf(image), mi.TensorXf(srgb_slope(image) ** 2 * inside),
                                      float(inside.sum() * 3))
        target, weight, count = targets[(view, light)]
        t0 = time.perf_counter()
        img = mi.render(scenes[view], p, spp=spp, seed=2 * it, seed_grad=2 * it + 1)
        # Eq. 10's tone-mapped MSE to first order about the target, (γ'(t)·(I − t))²: quadratic in the
        # render, so the gradient from independent primal and adjoint samples stays unbiased (γ of a noisy
        # render is darker on average than γ of its mean).
        loss = dr.sum(dr.square(img - target) * weight, axis=None) / count
        dr.backward(loss)
        opt.step()
        dr.eval(opt[key])
        seconds = time.perf_counter() - t0
        log["iteration"].append(it)
        log["loss"].append(float(loss.array[0]))
        log["seconds"].append(seconds)
        if log_every and (it % log_every == 0 or it == iterations - 1):
            print(f"iteration {it:4d}: loss {log['loss'][-1]:.3e}, {seconds:.2f} s", flush=True)
    weights = np.asarray(opt[key], dtype=np.float32)
    # The sampler follows the fitted weights again; the file loads like any other.
    return start.with_weights(weights).with_fitted_sampler(), log


def render_views(ds: Dataset, bsdf: Dict[str, Any], images: Sequence[Tuple[int, int]], work: Path,
                 spp: int, max_depth: int = 8, seed: int = 0) -> List[np.ndarray]:
    """Renders the data set's `images` ((view, light) pairs) with `bsdf` by Mitsuba's path tracer,
    every bounce included."""
    import mitsuba as mi

    out = []
    work.mkdir(parents=True, exist_ok=True)
    integrator = {"type": "path", "max_depth": max_depth, "rr_depth": max_depth}
    for view, light in images:
        scene = mi.load_dict(scene_dict(ds, bsdf, view, light, integrator, spp, work / "mesh.ply"))
        out.append(np.asarray(mi.render(scene, spp=spp, seed=seed), dtype=np.float32))
    return out


def main(argv: Optional[Sequence[str]] = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="a data set folder of trainer synth")
    start = ap.add_mutually_exclusive_group(required=True)
    start.add_argument("--init", type=Path, help="start from this .nbrdf model (e.g. a trainer fit)")
    start.add_argument("--model", help="start from scratch with this variant (fit's names: single-mlp, ...)")
    ap.add_argument("--enhanced", action="store_true", help="with --model: Eq. 8's enhanced additive split")
    ap.add_argument("--position", default="uniform",
                    help="with --model: uniform or extrinsic:F (the hit point, in the data set's unit-sphere frame)")
    ap.add_argument("--out", type=Path, required=True, help="the fitted .nbrdf model")
    ap.add_argument("--iterations", type=int, default=200)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--max-depth", type=int, default=4, help="surface vertices per path (2: direct light only)")
    ap.add_argument("--lr", type=float, default=1e-4)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    args = ap.parse_args(argv)

    import mitsuba as mi

    mi.set_variant(args.variant)
    import nbrdf.mitsuba  # registers the plugin for the variant

    ds = Dataset(args.data)
    if args.init is not None:
        model = nbrdf.Model.load(args.init)
    else:
        median = ds.spec.get("exposure", {}).get("median_luminance")
        model = nbrdf.init_model(args.model, enhanced=args.enhanced, position=args.position, median=median)
    work = args.out.parent / (args.out.stem + ".work")
    fitted, log = fit(ds, model, work, args.iterations, spp=args.spp, max_depth=args.max_depth, lr=args.lr)
    fitted.save(args.out)
    (work / "log.json").write_text(json.dumps(log))
    print(f"wrote {args.out} ({np.median(log['seconds']):.2f} s per iteration, median)")


if __name__ == "__main__":
    main()
