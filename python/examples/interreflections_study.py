"""What interreflections cost a direct-only fit, and how much a fit inside Mitsuba with every bounce
gives back.

For each concave object: a semi-synthetic data set whose images include the light that bounces
between the object's parts (``synth(interreflections=SPP)``, nbrdf's path tracer, noise as in the
paper), then the same model fitted two ways —

- **direct-only**: the trainer (Eq. 9: direct light with cast shadows), ``steps`` steps, and again
  with more steps so that it has the GI fit's wall time too;
- **GI**: that fit fine-tuned through Mitsuba's ``prb`` integrator (``fit_in_mitsuba.fit``),

and every model rendered at the held-out test views with every bounce (Mitsuba's ``path``, many
samples), scored against the ground-truth material rendered the same way: PSNR of the tone-mapped
images (Eq. 10's γ) over the object, and over its **recesses** (pixels where the interreflected light is
more than 10 % of the radiance, from the data set's own split of the two). Two more rows bound the
scores: the ground truth rendered again with other random numbers (the scoring renders' noise), and the
direct-only fit to the same object's data without interreflections (the fit's own error, so the part of
the direct-only fit's error that interreflections cause is the difference to it).

    python interreflections_study.py OUT [--objects grooved rocker-arm] [--material NAME] ...

Writes ``OUT/REPORT.md``, ``OUT/results.json`` and per object a PNG of one test image (reference,
both fits, their errors ×4, the recess mask).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import nbrdf  # noqa: E402
from fit_in_mitsuba import Dataset, fit, render_views, srgb  # noqa: E402


# The scoring renders share their random numbers (the same seed), so a fit's score measures its BRDF,
# not the renders' Monte Carlo noise; this row shows how large that noise is.
NOISE = "reference rendered with other random numbers"
# The direct-only fit to the same data set without interreflections: the error the fit makes when its
# model of the images is right, so what the interreflections add is the difference to it.
OWN = "direct-only, data without interreflections"
GI = "GI (Mitsuba prb)"


def png(path: Path, tiles: List[np.ndarray]) -> None:
    """A row of tiles (linear RGB shown through γ, or a mask) as one 8-bit PNG."""
    import mitsuba as mi

    rows = []
    for t in tiles:
        t = t.astype(np.float32)
        if t.ndim == 2:
            t = np.repeat(t[..., None], 3, axis=2)
        rows.append(np.clip(t, 0, 1))
    # Each pixel as 4 × 4, so that a 64² image reads on a page.
    strip = np.repeat(np.repeat(np.concatenate(rows, axis=1), 4, axis=0), 4, axis=1)
    mi.Bitmap((srgb(strip) * 255 + 0.5).astype(np.uint8), pixel_format=mi.Bitmap.PixelFormat.RGB).write(str(path))


def study_object(out: Path, mesh: str, material: Path, a: argparse.Namespace) -> Dict[str, Any]:
    name = Path(mesh).stem
    root = out / name
    data = root / "data"
    clean = root / "data-direct"
    # The same views, lights and noise, with and without the interreflected light.
    for folder, spp in ((data, a.data_spp), (clean, 0)):
        if not (folder / "dataset.json").exists():
            nbrdf.synth(folder, mesh=mesh, material=str(material), size=a.size, views=a.views,
                        train_views=a.train_views, train_lights=a.train_lights, test_lights=a.test_lights,
                        target_median=0.2, interreflections=spp, progress=False)
    ds = Dataset(data)
    common = dict(position=a.position, batch=a.batch, progress=False)
    # Direct-only: the trainer, Eq. 9.
    t0 = time.perf_counter()
    direct = nbrdf.fit(a.model, data=data, steps=a.steps, out=root / "direct", **common)
    direct_seconds = time.perf_counter() - t0
    # GI: the direct fit fine-tuned through Mitsuba's path replay.
    t0 = time.perf_counter()
    gi, log = fit(ds, direct.load(), root / "gi.work", a.iterations, spp=a.spp, max_depth=a.max_depth, lr=a.lr,
                  log_every=0)
    gi_seconds = time.perf_counter() - t0
    gi.save(root / "gi.nbrdf")
    # The same wall time spent on the direct-only fit instead: more steps at its measured rate.
    more = int(round(a.steps * (direct_seconds + gi_seconds) / direct_seconds))
    t0 = time.perf_counter()
    longer = nbrdf.fit(a.model, data=data, steps=more, out=root / "direct-long", **common)
    longer_seconds = time.perf_counter() - t0
    own = nbrdf.fit(a.model, data=clean, steps=a.steps, out=root / "direct-own", **common)

    tests = [(v, li) for v in ds.split("test") for li in range(len(ds.views[v]["images"]))]
    work = root / "render"
    bsdfs = {
        "reference": {"type": "nbrdf", "filename": str(material)},
        "direct-only": {"type": "nbrdf", "filename": str(direct.model)},
        "direct-only, same wall time": {"type": "nbrdf", "filename": str(longer.model)},
        GI: {"type": "nbrdf", "filename": str(root / "gi.nbrdf")},
        OWN: {"type": "nbrdf", "filename": str(own.model)},
    }
    renders = {k: render_views(ds, b, tests, work, spp=a.eval_spp, seed=1) for k, b in bsdfs.items()}
    again = render_views(ds, bsdfs["reference"], tests, work, spp=a.eval_spp, seed=2)
    scores: Dict[str, Dict[str, float]] = {}
    masks = []
    for v, li in tests:
        inside = ds.mask(v)
        radiance, indirect = ds.image(v, li), ds.image(v, li, "indirect")
        recess = inside & (indirect.mean(axis=2) > 0.1 * np.maximum(radiance.mean(axis=2), 1e-6))
        masks.append((inside, recess))
    rows = dict(renders)
    rows[NOISE] = again
    for k, imgs in rows.items():
        if k == "reference":
            continue
        # The study's PSNR (on γ, over the mask's pixels, every channel).
        ref = renders["reference"]
        whole = [nbrdf.compare(r, i, m[0])["psnr"] for i, r, m in zip(imgs, ref, masks)]
        recess = [nbrdf.compare(r, i, m[1])["psnr"] for i, r, m in zip(imgs, ref, masks) if m[1].sum() >= 10]
        scores[k] = {"psnr": float(np.mean(whole)), "psnr_recess": float(np.mean(recess))}
    recess_share = float(np.mean([m[1].sum() / max(m[0].sum(), 1) for m in masks]))
    # One test image: reference, the two fits, their errors ×4, the recess mask.
    j = int(np.argmax([m[1].sum() for m in masks]))
    ref, d, g = renders["reference"][j], renders["direct-only"][j], renders[GI][j]
    err = lambda x: np.abs(srgb(x) - srgb(ref)) * 4 * masks[j][0][..., None]  # noqa: E731
    png(out / f"{name}.png", [ref, d, g, err(d) ** 2.2, err(g) ** 2.2, masks[j][1]])
    return {
        "object": name,
        "material": material.stem,
        "recess_share": recess_share,
        "scores": scores,
        "direct_steps": a.steps,
        "direct_seconds": direct_seconds,
        "direct_long_steps": more,
        "direct_long_seconds": longer_seconds,
        "gi_iterations": a.iterations,
        "gi_seconds": gi_seconds,
        "gi_spp": a.spp,
        "gi_seconds_per_iteration": float(np.median(log["seconds"])),
        "gi_loss_first_last": [float(np.mean(log["loss"][:10])), float(np.mean(log["loss"][-10:]))],
        "gi_loss": log["loss"],
        "pixels_per_iteration": a.size * a.size * a.spp,
    }


def report(out: Path, results: List[Dict[str, Any]], a: argparse.Namespace) -> None:
    lines = [
        "# Interreflections: the direct-only fit against a fit inside Mitsuba with every bounce",
        "",
        f"Written by `python/examples/interreflections_study.py` ({a.model}, position {a.position}, "
        f"{a.size}×{a.size} images, {a.views} views ({a.train_views} for training) × {a.train_lights} lights, test "
        f"views × {a.test_lights}; data path-traced with {a.data_spp} spp of interreflected light; "
        f"trainer {a.steps} steps of {a.batch} pixels; GI fit {a.iterations} iterations of one {a.size}² image at "
        f"{a.spp} spp, up to {a.max_depth} vertices, lr {a.lr}; scored on Mitsuba `path` renders at {a.eval_spp} spp).",
        "",
        "PSNR (dB) of the tone-mapped test images against the ground truth rendered the same way and with the",
        "same random numbers, over the object and over its recesses (interreflected light > 10 % of the",
        "radiance). The last row of each object renders the ground truth with other random numbers: the size",
        "of the scoring renders' Monte Carlo noise, which the paired scores of the fits largely cancel.",
        "",
        "| object | recess share | model | PSNR | PSNR recesses | fit time |",
        "|---|---:|---|---:|---:|---|",
    ]
    for r in results:
        times = {
            "direct-only": f"{r['direct_seconds']:.0f} s ({r['direct_steps']} steps)",
            "direct-only, same wall time": f"{r['direct_long_seconds']:.0f} s ({r['direct_long_steps']} steps)",
            GI: f"+{r['gi_seconds']:.0f} s ({r['gi_iterations']} iterations, "
                                f"{r['gi_seconds_per_iteration']:.2f} s each)",
            OWN: f"{r['direct_steps']} steps",
            NOISE: "",
        }
        for k, s in r["scores"].items():
            lines.append(f"| {r['object']} ({r['material']}) | {r['recess_share']:.1%} | {k} | {s['psnr']:.2f} | "
                         f"{s['psnr_recess']:.2f} | {times[k]} |")
    lines += ["", "Share of the interreflections' error in the recesses (the direct-only fit's squared error less "
              "that of the fit to data without interreflections) that the GI fit removes:", ""]
    for r in results:
        mse = {k: 10 ** (-s["psnr_recess"] / 10) for k, s in r["scores"].items()}
        caused = mse["direct-only"] - mse[OWN]
        share = (mse["direct-only"] - mse[GI]) / caused if caused > 0 else float("nan")
        r["recess_error_removed"] = share
        lines.append(f"- {r['object']}: {share:.0%}")
    lines += ["", "Images (per object, one test image): reference, direct-only fit, GI fit, their errors ×4, recess mask.", ""]
    lines += [f"![{r['object']}]({r['object']}.png)" for r in results]
    (out / "REPORT.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps(results, indent=1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path)
    data = Path(os.environ.get("NBRDF_DATA", "../shared/data"))
    ap.add_argument("--objects", nargs="+", default=["grooved", str(data / "meshes/rocker-arm.obj")])
    ap.add_argument("--material", type=Path, default=data / "nbrdf-merl/white-paint.json")
    ap.add_argument("--model", default="additive-separate")
    ap.add_argument("--position", default="extrinsic:4",
                    help="the models' position input: extrinsic:F (x, y, z; what Mitsuba hands the plugin) or uniform")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--train-views", type=int, default=5)
    ap.add_argument("--train-lights", type=int, default=8)
    ap.add_argument("--test-lights", type=int, default=4)
    ap.add_argument("--data-spp", type=int, default=256)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--iterations", type=int, default=200)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--max-depth", type=int, default=8, help="the data's own path depth")
    ap.add_argument("--lr", type=float, default=2e-4)
    ap.add_argument("--eval-spp", type=int, default=256)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    a = ap.parse_args()
    import mitsuba as mi

    mi.set_variant(a.variant)
    import nbrdf.mitsuba  # noqa: F401  (registers the plugin)

    a.out.mkdir(parents=True, exist_ok=True)
    results = [study_object(a.out, m, a.material, a) for m in a.objects]
    report(a.out, results, a)
    print((a.out / "REPORT.md").read_text())


if __name__ == "__main__":
    main()
