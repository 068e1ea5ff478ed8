"""Renders a fitted nbrdf model on a mesh under an environment map in Mitsuba 3, through the "nbrdf"
BSDF plugin, and writes the image as OpenEXR (linear) and PNG (sRGB).

    python python/examples/render_mitsuba.py --model fitted.nbrdf --mesh ../shared/data/meshes/spot.obj \\
        --env sky.exr --out render.exr

Without --model it first fits one (a Single MLP, uniform over the surface) to a small semi-synthetic
data set of --material, as `trainer synth` and `trainer fit` would; without --env it makes a
procedural sky (a blue gradient, a warm sun and a dark ground) and writes it beside the output.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

import mitsuba as mi

import nbrdf


def procedural_sky(path: Path, width: int = 256) -> Path:
    """A lat-long HDR environment, +y up (Mitsuba's envmap convention): sky gradient, sun, ground."""
    h = width // 2
    theta = (np.arange(h) + 0.5) / h * np.pi  # from +y down
    phi = (np.arange(width) + 0.5) / width * 2 * np.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], axis=-1)
    up = np.clip(d[..., 1], 0, 1)[..., None]
    sky = (1 - up) * np.array([0.9, 0.95, 1.0]) + up * np.array([0.25, 0.45, 0.9])
    ground = np.array([0.12, 0.1, 0.08])
    img = np.where(d[..., 1:2] > 0, sky, ground)
    sun = np.array([0.5, 0.6, -0.62])
    sun /= np.linalg.norm(sun)
    img += np.exp((d @ sun - 1) * 400)[..., None] * np.array([60.0, 52.0, 40.0])
    mi.Bitmap(img.astype(np.float32)).write(str(path))
    return path


def fit_default(material: str, out: Path, steps: int) -> Path:
    data = nbrdf.synth(out / "data", material=material, size=64, views=12, train_views=8, train_lights=16,
                       test_lights=4)
    return nbrdf.fit("single-mlp", data=data, position="uniform", steps=steps, out=out / "fit").model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", type=Path, help="a fitted .nbrdf (or NBRDF-json .json, MERL .binary)")
    ap.add_argument("--material", default="two-lobe-metal", help="what to fit without --model")
    ap.add_argument("--steps", type=int, default=1500, help="training steps without --model")
    ap.add_argument("--mesh", default="sphere", help="sphere, torus, grooved, or an OBJ/PLY file")
    ap.add_argument("--env", type=Path, help="lat-long OpenEXR environment, +y up")
    ap.add_argument("--eye", default="0.6,0.9,3.6", help="camera position x,y,z (it looks at the origin)")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--variant", default="llvm_ad_rgb", help="an *_rgb variant: llvm_ad_rgb or scalar_rgb")
    ap.add_argument("--out", type=Path, default=Path("render.exr"))
    args = ap.parse_args()

    mi.set_variant(args.variant)
    import nbrdf.mitsuba  # registers the "nbrdf" BSDF for the variant just set

    work = Path(tempfile.mkdtemp(prefix="nbrdf-render-"))
    model = args.model or fit_default(args.material, work, args.steps)
    env = args.env or procedural_sky(args.out.with_name(args.out.stem + "-sky.exr"))
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 6},
        "sensor": {
            "type": "perspective",
            "fov": 35.0,
            "to_world": mi.ScalarTransform4f().look_at(origin=[float(x) for x in args.eye.split(",")], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": args.size, "height": args.size, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": args.spp},
        },
        "object": nbrdf.mitsuba.shape(args.mesh, str(work / "mesh.ply"), {"type": "nbrdf", "filename": str(model)}),
        "sky": {"type": "envmap", "filename": str(env)},
    })
    image = mi.render(scene, spp=args.spp)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    mi.Bitmap(image).write(str(args.out))
    png = args.out.with_suffix(".png")
    mi.util.convert_to_bitmap(image).write(str(png))
    print(f"rendered {model} on {args.mesh}: {args.out} and {png}")


if __name__ == "__main__":
    main()
