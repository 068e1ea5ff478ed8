"""The Mitsuba 3 plugin: the directions' conventions, the chi-square test of its sampling against its
density (a parametric and a fitted neural model), nbrdf's Lambert against Mitsuba's diffuse, the
white furnace, an NBRDF-json material rendered by Mitsuba and by nbrdf's own path tracer, and the
differentiable mode: its gradients against central differences and a fit through `prb`."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nbrdf
from conftest import need_json, unit_rows

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")


def use(variant: str) -> None:
    """Sets the variant and registers the plugin for it. The LLVM variants need libLLVM 16 or newer:
    Dr.Jit refuses 14, and 15 aborted the process in its AVX-512 code generation on this project's
    machines (`LLVM ERROR: Cannot select`), so they are skipped with the reason rather than run."""
    try:
        mi.set_variant(variant)
    except Exception as e:  # e.g. the LLVM backend without libLLVM
        pytest.skip(f"Mitsuba variant {variant} is not available here: {e}")
    if variant.startswith("llvm") and dr.detail.llvm_version() < (16,):
        pytest.skip(f"libLLVM {dr.detail.llvm_version()} is older than 16 (apt-get install libllvm19, or point "
                    "DRJIT_LIBLLVM_PATH at a newer libLLVM)")
    import nbrdf.mitsuba

    nbrdf.mitsuba.register()


@pytest.fixture(params=["scalar_rgb", "llvm_ad_rgb"])
def variant(request):
    use(request.param)
    return request.param


def bsdf(**props):
    return mi.load_dict({"type": "nbrdf", **props})


def fit_example():
    """python/examples/fit_in_mitsuba.py, imported as a module."""
    import importlib
    import sys
    from pathlib import Path

    examples = str(Path(__file__).resolve().parents[1] / "examples")
    if examples not in sys.path:
        sys.path.insert(0, examples)
    return importlib.import_module("fit_in_mitsuba")


def test_plugin_swaps_the_directions_and_adds_the_cosine(variant):
    """Mitsuba's si.wi is the viewer (nbrdf's wo), its wo the light (nbrdf's wi), its eval has the
    cosine: checked on a non-reciprocal BRDF, where swapping the two would show."""
    path = need_json("gold-metallic-paint")
    m = nbrdf.nbrdf_json(path)
    b = bsdf(filename=str(path))
    light = np.float32([[0.6, 0.1, 0.3]])
    view = np.float32([[-0.2, 0.5, 0.6]])
    light /= np.linalg.norm(light)
    view /= np.linalg.norm(view)
    want = m.eval(light, view)[0] * light[0, 2]
    assert np.abs(want - m.eval(view, light)[0] * light[0, 2]).max() > 1e-3 * want.max()  # not reciprocal here
    si = mi.SurfaceInteraction3f() if variant.startswith("scalar") else dr.zeros(mi.SurfaceInteraction3f, 1)
    si.wi = mi.Vector3f(*view[0].tolist())
    ctx = mi.BSDFContext()
    wo = mi.Vector3f(*light[0].tolist())
    got = np.asarray(b.eval(ctx, si, wo)).reshape(-1)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    value, pdf = b.eval_pdf(ctx, si, wo)
    np.testing.assert_allclose(np.asarray(value).reshape(-1), want, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(pdf).reshape(-1), m.pdf(light, view), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(b.pdf(ctx, si, wo)).reshape(-1), m.pdf(light, view), rtol=1e-6)
    bs, weight = b.sample(ctx, si, 0.3, mi.Point2f(0.6, 0.2))
    wi, w, p = m.sample(view, np.float32([[0.6, 0.2, 0.3]]))
    np.testing.assert_allclose(np.asarray(bs.wo).reshape(-1), wi[0], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(weight).reshape(-1), w[0], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(bs.pdf).reshape(-1), p, rtol=1e-6)
    # Seen from below the surface: nothing.
    si.wi = mi.Vector3f(0.0, 0.6, -0.8)
    assert np.asarray(b.eval(ctx, si, wo)).max() == 0


@pytest.mark.parametrize("wi", [[0.0, 0.0, 1.0], [0.6, 0.2, 0.77], [0.97, 0.0, 0.25]])
def test_chi2_parametric(wi):
    use("llvm_ad_rgb")
    # Lobes no sharper than the test's 101×101 tabulation of the density resolves (GGX α = 0.25, GTR1
    # α = 0.1): much sharper ones overshoot its trapezoid sums whatever the sampler.
    spec = "disney:0.7,0.5,0.3,0.0,0.3,0.5,0.0,0.5,0.25,0.0,0.5,0.0"
    sample, pdf = mi.chi2.BSDFAdapter("nbrdf", {"type": "nbrdf", "spec": spec}, wi=wi)
    test = mi.chi2.ChiSquareTest(domain=mi.chi2.SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3)
    assert test.run(), test.messages


@pytest.mark.parametrize("wi", [[0.0, 0.0, 1.0], [0.7, -0.3, 0.65]])
def test_chi2_fitted_model(fitted, wi):
    use("llvm_ad_rgb")
    sample, pdf = mi.chi2.BSDFAdapter("nbrdf", {"type": "nbrdf", "filename": str(fitted)}, wi=wi)
    test = mi.chi2.ChiSquareTest(domain=mi.chi2.SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3)
    assert test.run(), test.messages


def scene(bsdf: dict, shape: dict, size: int, spp: int) -> "mi.Scene":
    """A pinhole camera at (0, 0.6, 3.4) looking at the origin, a constant sky and a sun, as
    nbrdf.render's defaults and arguments below draw them."""
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 4},
        "sensor": {
            "type": "perspective",
            "fov": 40.0,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0.6, 3.4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "object": {**shape, "bsdf": bsdf},
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": SKY}},
        # Mitsuba's direction is the light's travel; nbrdf's points toward the light.
        "sun": {"type": "directional", "direction": [-x for x in SUN], "irradiance": {"type": "rgb", "value": SUN_RGB}},
    })


SKY, SUN, SUN_RGB = [0.3, 0.35, 0.4], [0.5, 0.8, 0.6], [2.0, 1.8, 1.5]


def renders(scn, seeds, spp) -> np.ndarray:
    return np.stack([np.asarray(mi.render(scn, seed=s, spp=spp), dtype=np.float64) for s in seeds])


def test_lambert_renders_as_mitsubas_diffuse():
    """nbrdf's Lambert through the plugin and Mitsuba's own diffuse agree per 8×8 pixel block within 3
    standard errors (estimated from 8 independent renderings of each)."""
    use("llvm_ad_rgb")
    size, spp, seeds = 32, 32, range(8)
    shape = {"type": "sphere"}
    ours = renders(scene({"type": "nbrdf", "spec": "lambert:0.7,0.5,0.3"}, shape, size, spp), seeds, spp)
    theirs = renders(scene({"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.5, 0.3]}}, shape, size, spp),
                     [100 + s for s in seeds], spp)

    def blocks(img):  # (seeds, H, W, 3) -> (seeds, blocks) of luminance means
        lum = img @ np.array([0.2126, 0.7152, 0.0722])
        return lum.reshape(len(img), size // 8, 8, size // 8, 8).mean(axis=(2, 4)).reshape(len(img), -1)

    a, b = blocks(ours), blocks(theirs)
    diff = a.mean(0) - b.mean(0)
    se = np.sqrt(a.var(0, ddof=1) / len(a) + b.var(0, ddof=1) / len(b))
    assert (np.abs(diff) <= 3 * se + 1e-6).all(), (diff, se)
    assert a.mean() > 0.1 and se.max() > 0  # the sphere is lit and seen, and noisy


def test_white_furnace(variant):
    """A white Lambertian sphere under a white sky through the plugin is as bright as the sky."""
    size, spp = (8, 16) if variant.startswith("scalar") else (32, 64)
    scn = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 6},
        "sensor": {
            "type": "perspective", "fov": 30.0,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "object": {"type": "sphere", "bsdf": {"type": "nbrdf", "spec": "lambert:1,1,1"}},
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
    })
    img = np.asarray(mi.render(scn, spp=spp), dtype=np.float64)
    assert abs(img.mean() - 1.0) < 0.01, img.mean()
    assert np.abs(img - 1.0).max() < 0.25  # no pixel far off (each is a mean of spp paths)


def test_nbrdf_json_renders_the_same_in_mitsuba_and_in_nbrdf(tmp_path):
    """The same NBRDF-json material on the same mesh under the same camera and lights: the image means
    of Mitsuba (through the plugin) and of nbrdf's path tracer agree within 3 of their combined
    standard errors, per channel."""
    path = need_json("gold-metallic-paint")
    use("llvm_ad_rgb")
    import nbrdf.mitsuba

    size, spp = 48, 64
    seeds = range(6)
    scn = scene({"type": "nbrdf", "filename": str(path)}, nbrdf.mitsuba.shape("sphere", str(tmp_path / "sphere.ply")), size, spp)
    ours = renders(scn, seeds, spp).mean(axis=(1, 2))  # (seeds, 3) image means
    img, var = nbrdf.render(nbrdf.nbrdf_json(path), mesh="sphere", width=size, height=size, fov=40.0,
                            lights=[(SUN, SUN_RGB)], env_color=SKY, spp=4 * spp, seed=1)
    theirs = img.astype(np.float64).mean(axis=(0, 1))
    se_theirs = np.sqrt(var.astype(np.float64).sum(axis=(0, 1))) / (size * size)
    se_ours = ours.std(axis=0, ddof=1) / np.sqrt(len(ours))
    diff = ours.mean(axis=0) - theirs
    assert (np.abs(diff) <= 3 * np.sqrt(se_ours**2 + se_theirs**2)).all(), (diff, se_ours, se_theirs)
    # The object covers a fair part of the frame and is not the sky: the means see the BRDF.
    assert (np.abs(img - np.float32(SKY)).max(axis=2) > 0.02).mean() > 0.3


def test_plugin_rejects_what_it_cannot_render(tmp_path):
    use("llvm_ad_rgb")
    with pytest.raises(Exception, match="filename"):
        bsdf()
    with pytest.raises(Exception, match="missing.nbrdf"):
        bsdf(filename=str(tmp_path / "missing.nbrdf"))


def test_spatially_varying_model_reads_the_hit_point(fitted_extrinsic, variant):
    """An extrinsically encoded model gets si.p, mapped by position_transform, as its point input."""
    m = nbrdf.Model.load(fitted_extrinsic)
    to_model = mi.ScalarTransform4f().scale(0.5)
    b = bsdf(filename=str(fitted_extrinsic), position_transform=to_model)
    light = np.float32([[0.3, 0.2, 0.93]])
    view = np.float32([[-0.4, 0.1, 0.91]])
    light /= np.linalg.norm(light)
    view /= np.linalg.norm(view)
    ctx = mi.BSDFContext()
    for p in [[0.2, -0.6, 1.0], [-1.4, 0.4, 0.2]]:
        si = mi.SurfaceInteraction3f() if variant.startswith("scalar") else dr.zeros(mi.SurfaceInteraction3f, 1)
        si.wi = mi.Vector3f(*view[0].tolist())
        si.p = mi.Point3f(*p)
        got = np.asarray(b.eval(ctx, si, mi.Vector3f(*light[0].tolist()))).reshape(-1)
        want = m.eval(light, view, np.float32(p) * 0.5)[0] * light[0, 2]
        np.testing.assert_allclose(got, want, rtol=1e-6)
    assert not np.allclose(m.eval(light, view, np.float32([0.1, -0.3, 0.5])), m.eval(light, view, np.float32([-0.7, 0.2, 0.1])))


# The three model families of the differentiable plugin: a Single MLP, an enhanced Additive Separate
# and a parametric model whose parameters an MLP predicts; extrinsic, so the hit point matters.
GRADIENT_MODELS = [
    dict(model="single-mlp"),
    dict(model="additive-separate", enhanced=True, reciprocity="none"),
    dict(model="ts"),
]


def initial_file(tmp_path, spec: dict, seed: int = 3):
    m = nbrdf.init_model(**spec, position="extrinsic:2", seed=seed, median=0.5)
    path = tmp_path / "start.nbrdf"
    m.save(path)
    return m, path


def central_difference(loss, w0: np.ndarray, i: int, h: float = 2e-3) -> float:
    up, down = w0.copy(), w0.copy()
    up[i] += h
    down[i] -= h
    return (loss(up) - loss(down)) / (2 * h)


def check_against_differences(grad: np.ndarray, loss, w0: np.ndarray, rng) -> None:
    """The largest components and a few random ones agree with central differences of `loss`."""
    largest = np.abs(grad).max()
    assert largest > 0
    picks = list(np.argsort(-np.abs(grad))[:4]) + list(rng.integers(0, len(w0), 4))
    for i in picks:
        fd = central_difference(loss, w0, int(i))
        assert abs(fd - grad[i]) <= 0.03 * abs(grad[i]) + 2e-3 * largest, (int(i), grad[i], fd, largest)


@pytest.mark.parametrize("spec", GRADIENT_MODELS, ids=lambda s: s["model"])
def test_differentiable_plugin_gradients_of_eval_and_sample_match_central_differences(tmp_path, spec):
    """`differentiable=True`: eval's value and sample's weight carry gradients to the weights (the
    scene parameter `weights`), equal to central differences of the core's values."""
    use("llvm_ad_rgb")
    m, path = initial_file(tmp_path, spec)
    b = bsdf(filename=str(path), differentiable=True)
    params = mi.traverse(b)
    assert list(params.keys()) == ["weights"] and dr.width(params["weights"]) == m.n_parameters
    w = params["weights"]
    w0 = m.weights
    dr.enable_grad(w)
    rng = np.random.default_rng(0)
    n = 64
    view, light = unit_rows(rng, n), unit_rows(rng, n)
    points = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    g = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi, si.p = mi.Vector3f(view.T), mi.Point3f(points.T)
    ctx = mi.BSDFContext()

    # eval: Mitsuba's value is f cos θ of the light direction.
    value = b.eval(ctx, si, mi.Vector3f(light.T))
    dr.backward(dr.sum(dr.sum(value * mi.Color3f(g.T)), axis=None))
    grad = np.asarray(dr.grad(w)).copy()
    def eval_loss(weights):
        return float((m.with_weights(weights).eval(light, view, points).astype(np.float64) * light[:, 2:3] * g).sum())
    check_against_differences(grad, eval_loss, w0, rng)
    # eval_pdf's value is eval's, with the same gradient.
    dr.set_grad(w, 0.0)
    value, _ = b.eval_pdf(ctx, si, mi.Vector3f(light.T))
    dr.backward(dr.sum(dr.sum(value * mi.Color3f(g.T)), axis=None))
    np.testing.assert_allclose(np.asarray(dr.grad(w)), grad, rtol=1e-5, atol=1e-6 * np.abs(grad).max())

    # sample: the weight f cos / pdf at directions and a density that do not depend on the weights.
    dr.set_grad(w, 0.0)
    u = rng.random((n, 3)).astype(np.float32)
    bs, weight = b.sample(ctx, si, mi.Float(u[:, 2]), mi.Point2f(u[:, :2].T))
    dr.backward(dr.sum(dr.sum(weight * mi.Color3f(g.T)), axis=None))
    grad = np.asarray(dr.grad(w)).copy()
    wi, pdf = np.asarray(bs.wo).T.astype(np.float32), np.asarray(bs.pdf)
    ok = pdf > 0
    assert ok.mean() > 0.5
    def sample_loss(weights):
        f = m.with_weights(weights).eval(wi[ok], view[ok], points[ok]).astype(np.float64)
        return float((f * (wi[ok, 2] / pdf[ok])[:, None] * g[ok]).sum())
    check_against_differences(grad, sample_loss, w0, rng)


def test_prb_gradient_of_a_render_is_the_derivative_of_the_same_render(tmp_path):
    """Path replay (Mitsuba's `prb`, emitter sampling and BSDF sampling with MIS, one indirect
    bounce) differentiates a fixed-seed render through the plugin: its gradient equals central
    differences of the renders (Russian roulette off, so the paths do not depend on the weights)."""
    use("llvm_ad_rgb")
    m, path = initial_file(tmp_path, GRADIENT_MODELS[1], seed=5)
    size, spp = 16, 4
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "prb", "max_depth": 3, "rr_depth": 100},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "object": {"type": "sphere", "bsdf": {"type": "nbrdf", "filename": str(path), "differentiable": True}},
        "light": {"type": "point", "position": [2, 2, 3], "intensity": {"type": "rgb", "value": [20, 20, 20]}},
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [0.3, 0.3, 0.3]}},
    })
    params = mi.traverse(scene)
    key = "object.bsdf.weights"
    rng = np.random.default_rng(1)
    g = rng.uniform(-1, 1, (size, size, 3)).astype(np.float32)
    w0 = m.weights
    dr.enable_grad(params[key])
    # The adjoint pass with the primal's seed: the derivative of exactly that render.
    scene.integrator().render_backward(scene, params, mi.TensorXf(g), seed=5, spp=spp)
    grad = np.asarray(dr.grad(params[key])).copy()

    def loss(weights):
        params[key] = mi.Float(weights)
        params.update()
        with dr.suspend_grad():
            img = mi.render(scene, params, seed=5, spp=spp)
        return float((np.asarray(img, dtype=np.float64) * g).sum())

    check_against_differences(grad, loss, w0, rng)


def test_differentiable_plugin_refuses_what_it_cannot_differentiate(tmp_path):
    use("llvm_ad_rgb")
    with pytest.raises(Exception, match="no network weights"):
        bsdf(spec="lambert:0.5,0.5,0.5", differentiable=True)
    m, path = initial_file(tmp_path, GRADIENT_MODELS[0])
    use("scalar_rgb")
    with pytest.raises(Exception, match="_ad_rgb variant"):
        bsdf(filename=str(path), differentiable=True)


def test_fit_in_mitsuba_example_fits_from_images_and_writes_a_loadable_model(tmp_path):
    """python/examples/fit_in_mitsuba.py: a data set with interreflections, a short fit through `prb`
    from scratch, and a .nbrdf that the core loads, with other weights and a sampler of its own."""
    use("llvm_ad_rgb")
    fit_in_mitsuba = fit_example()

    data = nbrdf.synth(tmp_path / "data", mesh="grooved", material="lambert:0.7,0.6,0.5", size=24, views=3,
                       train_views=2, train_lights=2, test_lights=1, interreflections=4, target_median=0.2,
                       progress=False)
    out = tmp_path / "gi.nbrdf"
    fit_in_mitsuba.main([str(data), "--model", "additive-separate", "--out", str(out), "--iterations", "4",
                         "--spp", "2", "--max-depth", "3", "--lr", "1e-3"])
    m = nbrdf.Model.load(out)
    start = nbrdf.init_model("additive-separate", position="uniform",
                             median=fit_in_mitsuba.Dataset(data).spec["exposure"]["median_luminance"])
    assert m.kind == "model" and m.position_len == 0 and m.n_parameters == start.n_parameters
    assert not np.array_equal(m.weights, start.weights), "the fit moved the weights"
    rng = np.random.default_rng(2)
    wi, wo = unit_rows(rng, 16), unit_rows(rng, 16)
    assert np.isfinite(m.eval(wi, wo)).all()
    # Its sampler is the one fitted to the fitted weights.
    np.testing.assert_array_equal(m.pdf(wi, wo), m.with_weights(m.weights).with_fitted_sampler().pdf(wi, wo))
    log = json.loads((tmp_path / "gi.work" / "log.json").read_text())
    assert len(log["loss"]) == 4 and all(np.isfinite(log["loss"]))


def test_fit_in_mitsuba_renders_the_rays_the_data_set_sampled(tmp_path):
    """The data set's images sample each pixel's centre; `prb_pixel_centre` renders those rays, so the
    ground-truth material reproduces its images to their noise, where Mitsuba's area-averaged pixels
    differ along the silhouette and shadow edges."""
    use("llvm_ad_rgb")
    fm = fit_example()

    data = nbrdf.synth(tmp_path / "data", mesh="grooved", material="lambert:0.7,0.6,0.5", size=32, views=2,
                       train_views=1, train_lights=2, test_lights=1, target_median=0.2, progress=False)
    ds = fm.Dataset(data)
    bsdf = {"type": "nbrdf", "spec": "lambert:0.7,0.6,0.5"}
    view = ds.split("train")[0]
    errors = {}
    for name in (fm.register_pixel_centre_prb(), "prb"):
        scene = mi.load_dict(fm.scene_dict(ds, bsdf, view, 1, {"type": name, "max_depth": 2}, 4, tmp_path / "mesh.ply"))
        image = np.asarray(mi.render(scene, spp=4), dtype=np.float32)
        errors[name] = float(np.mean(((image - ds.image(view, 1)) ** 2)[ds.mask(view, erode=0)]))
    sigma = float(ds.spec["noise_sigma"])
    assert errors["prb_pixel_centre"] < 4 * sigma**2 + 1e-7, errors
    assert errors["prb"] > 10 * errors["prb_pixel_centre"], errors
