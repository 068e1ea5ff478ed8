"""The package's API: what each constructor makes, sampling against the density, bad input as
exceptions (never a crash), and the trainer's synth, fit and metrics."""

from __future__ import annotations

import _thread
import signal
import threading
import time

import numpy as np
import pytest

import nbrdf
from conftest import need_json, unit_rows


def test_constructors_and_properties(fitted, fitted_extrinsic):
    m = nbrdf.Model.load(fitted)
    assert (m.kind, m.position_len, m.parametric_kind) == ("model", 0, None)
    assert m.is_reciprocal  # the trainer's default reciprocity is the exact map Θ
    assert m.n_parameters > 1000
    assert "model" in repr(m)
    same = nbrdf.Model.from_bytes(fitted.read_bytes())
    rng = np.random.default_rng(0)
    wi, wo = unit_rows(rng, 64), unit_rows(rng, 64)
    np.testing.assert_array_equal(same.eval(wi, wo), m.eval(wi, wo))
    e = nbrdf.Model.load(fitted_extrinsic)
    assert (e.position_len, e.has_position_table) == (3, False)
    for brdf, kind in [
        (nbrdf.lambert([0.5, 0.5, 0.5]), "lambert"),
        (nbrdf.phong([0.3] * 3, [0.5] * 3, 20.0), "phong"),
        (nbrdf.torrance_sparrow([0.3] * 3, [0.5] * 3, 0.3), "torrance-sparrow"),
        (nbrdf.fmbrdf([0.3] * 3, 0.5, 0.3, 0.8, 1.5, 1.0), "fmbrdf"),
        (nbrdf.disney([0.5, 0.4, 0.3], roughness=0.3), "disney"),
    ]:
        assert (brdf.kind, brdf.parametric_kind, brdf.is_reciprocal) == ("parametric", kind, True)
    assert nbrdf.builtin("velvet").kind == "builtin"
    assert nbrdf.kernel_level() in ("avx512", "avx2", "neon", "portable")


def test_lambert_values_and_sampling_are_exact():
    m = nbrdf.lambert([0.8, 0.5, 0.2])
    rng = np.random.default_rng(1)
    wi, wo = unit_rows(rng, 100), unit_rows(rng, 100)
    np.testing.assert_allclose(m.eval(wi, wo), np.tile(np.float32([0.8, 0.5, 0.2]) / np.pi, (100, 1)), rtol=1e-6)
    np.testing.assert_allclose(m.pdf(wi, wo), wi[:, 2] / np.pi, rtol=1e-5)
    s_wi, weight, pdf = m.sample(wo, rng.random((100, 3), dtype=np.float32))
    np.testing.assert_allclose(weight, np.tile([0.8, 0.5, 0.2], (100, 1)), rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(s_wi, axis=1), 1.0, rtol=1e-5)
    assert (s_wi[:, 2] > 0).all()


def test_sample_density_and_weight_are_consistent(fitted):
    """For every sample: pdf == pdf(wi, wo) and weight == f cos / pdf (the Brdf trait's contract, to
    the rounding of a wo that is unit only to float32 precision, which sharp lobes magnify)."""
    for m in [nbrdf.Model.load(fitted), nbrdf.disney([0.6, 0.5, 0.4], metallic=0.5, roughness=0.2), nbrdf.builtin("clear-coat")]:
        rng = np.random.default_rng(2)
        wo = unit_rows(rng, 4000)
        wi, weight, pdf = m.sample(wo, rng.random((4000, 3), dtype=np.float32))
        ok = pdf > 0
        assert ok.mean() > 0.5
        np.testing.assert_allclose(m.pdf(wi[ok], wo[ok]), pdf[ok], rtol=1e-4)
        f = m.eval(wi[ok], wo[ok])
        np.testing.assert_allclose(weight[ok], f * wi[ok, 2:3] / pdf[ok, None], rtol=1e-4, atol=1e-7)


def test_points_per_pair_and_one_point(fitted_extrinsic):
    m = nbrdf.Model.load(fitted_extrinsic)
    rng = np.random.default_rng(4)
    wi, wo = unit_rows(rng, 50), unit_rows(rng, 50)
    p = rng.uniform(-1, 1, (50, 3)).astype(np.float32)
    per_pair = m.eval(wi, wo, p)
    # One point for all pairs equals that point repeated.
    np.testing.assert_array_equal(m.eval(wi, wo, p[7]), m.eval(wi, wo, np.tile(p[7], (50, 1))))
    np.testing.assert_array_equal(m.eval(wi[7:8], wo[7:8], p[7])[0], per_pair[7])
    with pytest.raises(ValueError, match="varies over the surface"):
        m.eval(wi, wo)
    with pytest.raises(ValueError, match=r"wi \(50,\), wo \(50,\), points \(10,\) do not broadcast"):
        m.eval(wi, wo, p[:10])
    with pytest.raises(ValueError, match=r"points must have shape \(3,\) for one point"):
        m.eval(wi, wo, p[:, :2])
    with pytest.raises(ValueError, match="same at every point"):
        nbrdf.lambert([0.5] * 3).eval(wi, wo, p)


def test_bad_input_raises_instead_of_crashing(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.nbrdf"):
        nbrdf.Model.load(tmp_path / "missing.nbrdf")
    with pytest.raises(FileNotFoundError):
        nbrdf.nbrdf_json(tmp_path / "missing.json")
    with pytest.raises(ValueError, match="unknown BRDF file type"):
        nbrdf.Model.load(tmp_path / "model.txt")
    bad = tmp_path / "bad.nbrdf"
    bad.write_bytes(b"not a model at all" * 10)
    with pytest.raises(ValueError, match="magic"):
        nbrdf.Model.load(bad)
    with pytest.raises(ValueError):
        nbrdf.Model.from_bytes(b"")
    with pytest.raises(ValueError):
        nbrdf.Model.from_bytes(b"{}", format="json")
    with pytest.raises(ValueError, match="kd \\+ ks|energy|<= 1|sum"):
        nbrdf.phong([0.8] * 3, [0.5] * 3, 10.0)
    with pytest.raises(ValueError, match="alpha"):
        nbrdf.torrance_sparrow([0.3] * 3, [0.3] * 3, 0.0)
    with pytest.raises(ValueError, match="\\[0, 1\\]"):
        nbrdf.lambert([1.5, 0.5, float("nan")])
    with pytest.raises(ValueError, match="unknown built-in"):
        nbrdf.builtin("chrome")
    with pytest.raises(ValueError, match="raw values"):
        nbrdf.parametric_from_raw("disney", [0.0])

    m = nbrdf.lambert([0.5] * 3)
    good = np.array([[0.0, 0.0, 1.0]], np.float32)
    with pytest.raises(ValueError, match=r"wo must have shape \(3,\) or \(N, 3\).*; got float32 array of shape \(1, 4\)"):
        m.eval(good, np.zeros((1, 4), np.float32))
    with pytest.raises(ValueError, match=r"wi \(2,\), wo \(3,\) do not broadcast"):
        m.eval(np.repeat(good, 2, axis=0), np.repeat(good, 3, axis=0))
    with pytest.raises(ValueError, match="u must have shape"):
        m.sample(good, np.zeros((1, 2), np.float32))
    # Empty batches are fine.
    assert m.eval(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32)).shape == (0, 3)


def test_non_finite_and_below_horizon_directions_give_documented_zeros(fitted):
    rows = np.array([[np.nan, 0, 1], [0, 0, np.inf], [0, 0, -1], [0, 0, 0], [0.6, 0, 0.8]], np.float32)
    view = np.tile(np.float32([[0.0, 0.6, 0.8]]), (5, 1))
    for m in [nbrdf.Model.load(fitted), nbrdf.lambert([0.5] * 3), nbrdf.builtin("two-lobe-metal")]:
        f, p = m.eval(rows, view), m.pdf(rows, view)
        assert np.isfinite(f).all() and np.isfinite(p).all()
        assert (f[:4] == 0).all() and (p[:4] == 0).all() and (f[4] > 0).all()
        wi, weight, pdf = m.sample(rows, np.full((5, 3), 0.5, np.float32))  # the rows as views
        assert np.isfinite(wi).all() and np.isfinite(weight).all()
        assert (pdf[:4] == 0).all() and (weight[:4] == 0).all() and pdf[4] > 0


def test_calls_release_the_gil(fitted):
    """While one thread evaluates a large batch, Python code keeps running in another (it could not if
    the call held the GIL), and two threads evaluating at once get the values of one alone."""
    m = nbrdf.Model.load(fitted)
    rng = np.random.default_rng(5)
    wi, wo = unit_rows(rng, 1_000_000), unit_rows(rng, 1_000_000)
    want = m.eval(wi[:20000], wo[:20000])
    done = threading.Event()
    got = []

    def work():
        start = time.perf_counter()
        got.append(m.eval(wi, wo))
        got.append(time.perf_counter() - start)
        done.set()

    t = threading.Thread(target=work)
    last = time.perf_counter()
    longest = 0.0
    t.start()
    while not done.is_set():
        now = time.perf_counter()
        longest, last = max(longest, now - last), now
    t.join()
    # Holding the GIL, the call would stop this loop for all of its duration.
    assert got[1] > 0.1 and longest < got[1] / 2, (longest, got[1])
    np.testing.assert_array_equal(got[0][:20000], want)
    both = [None, None]
    threads = [threading.Thread(target=lambda i=i: both.__setitem__(i, m.eval(wi[:20000], wo[:20000]))) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for g in both:
        np.testing.assert_array_equal(g, want)


def test_progress_bars_only_on_a_terminal(monkeypatch):
    class Stream:
        def __init__(self, tty):
            self.tty = tty

        def isatty(self):
            return self.tty

    monkeypatch.setattr("sys.stderr", Stream(True))
    assert nbrdf._interactive()
    monkeypatch.setattr("sys.stderr", Stream(False))  # a pipe, a file, a notebook's stream
    assert not nbrdf._interactive()
    monkeypatch.setattr("sys.stderr", object())  # a stream without isatty
    assert not nbrdf._interactive()
    monkeypatch.setattr("sys.stderr", None)  # pythonw
    assert not nbrdf._interactive()


def test_from_spec_matches_the_constructors():
    rng = np.random.default_rng(6)
    wi, wo = unit_rows(rng, 32), unit_rows(rng, 32)
    pairs = [
        ("lambert:0.2,0.3,0.4", nbrdf.lambert([0.2, 0.3, 0.4])),
        ("phong:0.3,0.2,0.1,0.5,0.5,0.5,40", nbrdf.phong([0.3, 0.2, 0.1], [0.5] * 3, 40)),
        ("builtin:velvet", nbrdf.builtin("velvet")),
    ]
    for spec, m in pairs:
        np.testing.assert_array_equal(nbrdf.from_spec(spec).eval(wi, wo), m.eval(wi, wo))
    with pytest.raises(ValueError, match="unknown kind"):
        nbrdf.from_spec("plastic:1,2,3")
    with pytest.raises(ValueError, match="expected 3"):
        nbrdf.from_spec("lambert:0.5,0.5")


def test_synth_fit_and_compare(tmp_path):
    data = nbrdf.synth(tmp_path / "data", material="lambert:0.6,0.5,0.4", size=32, views=4, train_views=2,
                       train_lights=3, test_lights=2, progress=False)
    assert (data / "dataset.json").is_file()
    result = nbrdf.fit("lambert", data=data, position="uniform", steps=30, batch=512, out=tmp_path / "fit",
                       progress=False)
    assert result.model.is_file() and result.model.suffix == ".nbrdf"
    assert result.log["steps_done"] == 30 and len(result.log["loss"]) > 0
    assert nbrdf.Model.load(result.model).position_len == 0
    # The result as Python objects: the loaded model and the learning curve as arrays.
    assert result.load().position_len == 0
    curve = result.curve
    assert curve["step"][-1] == 30 and len({len(v) for v in curve.values()}) == 1
    assert np.isfinite(curve["train_loss"][1:]).all() and np.isnan(curve["test_psnr"]).all()
    # Energy-bounded: the albedo table travels with the model, and the values are the unbounded
    # network's divided where it passes 1, the same for both orders of a pair.
    bounded = nbrdf.fit("single-mlp", toy=500, position="uniform", steps=5, batch=256, out=tmp_path / "bounded",
                        energy_bound=True, progress=False).load()
    table = bounded.albedo_bound
    assert table.shape == (32, 3) and table.dtype == np.float32 and (table > 0).all()
    assert result.load().albedo_bound is None
    rng = np.random.default_rng(3)
    wi, wo = (v / np.linalg.norm(v, axis=-1, keepdims=True) for v in (rng.normal(size=(64, 3)) for _ in range(2)))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    np.testing.assert_array_equal(bounded.eval(wi, wo), bounded.eval(wo, wi))
    # Its gradient is refused (the bound belongs to these weights); with_weights drops the bound.
    with pytest.raises(ValueError, match="energy-bounded"):
        bounded.weight_gradient(wi, wo, np.ones(3))
    assert bounded.with_weights(bounded.weights).albedo_bound is None
    with pytest.raises(ValueError, match="unknown model"):
        nbrdf.fit("plastic", toy=10, out=tmp_path / "x", progress=False)
    with pytest.raises(ValueError, match="--data DIR, --diligent PATH or --toy N"):
        nbrdf.fit("lambert", out=tmp_path / "x", progress=False)
    with pytest.raises(FileNotFoundError):
        nbrdf.fit("lambert", data=tmp_path / "nowhere", position="uniform", out=tmp_path / "x", progress=False)
    with pytest.raises(ValueError, match="^size 0: allowed"):  # named as the keyword argument
        nbrdf.synth(tmp_path / "bad", size=0, progress=False)

    # The study's metrics: identical renderings score perfectly, a brighter one worse on each.
    img = nbrdf.render(nbrdf.lambert([0.5] * 3), width=40, height=36, env_color=[1, 1, 1], spp=4)[0]
    same = nbrdf.compare(img, img)
    assert same["psnr"] == float("inf") and same["dssim"] == 0 and same["flip"] == 0
    worse = nbrdf.compare(img, img * 1.3, mask=img[..., 0] > 0.01)
    assert np.isfinite(worse["psnr"]) and worse["dssim"] > 0 and worse["flip"] > 0
    if worse["lpips"] is None:
        assert worse["lpips_na"].startswith("n/a")
    else:
        assert worse["lpips"] > 0 and same["lpips"] == 0
    with pytest.raises(ValueError, match="40×36 but test is 36×40"):
        nbrdf.compare(img, img.transpose(1, 0, 2).copy())
    with pytest.raises(ValueError, match="mask has shape"):
        nbrdf.compare(img, img, mask=np.ones((2, 2), bool))
    pred = np.full((10, 3), 0.5, np.float32)
    rmse, used = nbrdf.brdf_rmse(pred, pred * 8, keep=[True] * 5 + [False] * 5)
    assert used == 5 and abs(rmse - (2 - 1) * 0.5 ** (1 / 3)) < 1e-6


def test_render_returns_the_mean_and_its_variance():
    img, var = nbrdf.render(nbrdf.lambert([1.0, 1.0, 1.0]), width=24, height=20, env_color=[1, 1, 1], spp=8)
    assert img.shape == var.shape == (20, 24, 3)
    # The white furnace: a white Lambertian under a white sky is white everywhere, object or not,
    # within each pixel's Monte Carlo error.
    assert (np.abs(img - 1.0) <= 5 * np.sqrt(var) + 1e-5).all()
    assert var.max() < 0.05
    with pytest.raises(ValueError, match="no light"):
        nbrdf.render(nbrdf.lambert([1.0] * 3), width=8, height=8)
    with pytest.raises(FileNotFoundError):
        nbrdf.render(nbrdf.lambert([1.0] * 3), mesh="/nonexistent.obj", env_color=[1, 1, 1])


@pytest.mark.parametrize(
    "kwargs, error, names",
    [
        ({"spp": 0}, ValueError, "spp 0"),
        ({"spp": 2**20 + 1}, ValueError, "spp"),
        ({"spp": -1}, ValueError, "spp -1"),
        ({"spp": 2**200}, OverflowError, "spp"),
        ({"spp": 4.5}, TypeError, "spp"),
        ({"max_depth": 0}, ValueError, "max_depth 0"),
        ({"max_depth": 1025}, ValueError, "max_depth"),
        ({"width": 2**32 + 8}, ValueError, "width"),
        ({"height": -5}, ValueError, "height -5"),
        ({"seed": -1}, ValueError, "seed -1"),
        ({"seed": 2**64}, ValueError, "seed"),
    ],
)
def test_render_integers_are_checked_before_any_work_naming_the_argument(kwargs, error, names):
    args = {"width": 8, "height": 8, "env_color": [1, 1, 1], "spp": 1, **kwargs}
    with pytest.raises(error, match=names):
        nbrdf.render(nbrdf.lambert([0.5] * 3), **args)
    # The limits themselves are accepted, and numpy integers are integers.
    nbrdf.render(nbrdf.lambert([0.5] * 3), width=np.int64(4), height=4, env_color=[1, 1, 1], spp=1, max_depth=1024, seed=2**64 - 1)


def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_an_interrupt_stops_fit_within_a_second_and_leaves_the_earlier_fit_as_it_was(tmp_path):
    # Under Python's own Ctrl-C handler, which a process started in the background by a shell without
    # job control lacks (SIGINT is ignored there, and interrupt_main then does nothing).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _interrupt_fit(tmp_path)
    finally:
        signal.signal(signal.SIGINT, previous)


def _interrupt_fit(tmp_path):
    data = nbrdf.synth(tmp_path / "data", material="lambert:0.6,0.5,0.4", size=32, views=4, train_views=2,
                       train_lights=3, test_lights=2, progress=False)
    out = tmp_path / "fit"
    nbrdf.fit("single-mlp", data=data, position="uniform", steps=5, batch=256, out=out, progress=False)
    before = _snapshot(out)
    # Ctrl-C (or a notebook's interrupt) one second into a fit that would run for a minute or more (not
    # for hours: an interrupt that is lost fails the test instead of hanging it).
    timer = threading.Timer(1.0, _thread.interrupt_main)
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        nbrdf.fit("single-mlp", data=data, position="uniform", steps=20_000, batch=256, out=out, progress=False)
    timer.join()
    assert time.monotonic() - start < 2.0, "control returns within a second of the interrupt"
    assert _snapshot(out) == before, "the interrupted fit left the earlier one as it was"
    # The next call runs normally: the stop request was withdrawn.
    nbrdf.fit("single-mlp", data=data, position="uniform", steps=5, batch=256, out=tmp_path / "again", progress=False)


def test_progress_can_be_any_callable_fed_done_and_total(tmp_path):
    images, steps = [], []
    data = nbrdf.synth(tmp_path / "data", material="lambert:0.6,0.5,0.4", size=32, views=4, train_views=2,
                       train_lights=3, test_lights=2, progress=lambda done, total: images.append((done, total)))
    nbrdf.fit("lambert", data=data, position="uniform", steps=40, batch=256, out=tmp_path / "fit",
              progress=lambda done, total: steps.append((done, total)))
    # The last report is the whole run; reports never go back.
    assert images[-1] == (2 * 3 + 2 * 2, 2 * 3 + 2 * 2) and steps[-1] == (40, 40)
    assert all(a[0] <= b[0] for a, b in zip(steps, steps[1:]))
    # An exception raised by the callable stops the work like an interrupt and reaches the caller.
    def refuse(done: int, total: int) -> None:
        raise RuntimeError("stop here")
    with pytest.raises(RuntimeError, match="stop here"):
        nbrdf.fit("lambert", data=data, position="uniform", steps=10**6, batch=256, out=tmp_path / "never",
                  progress=refuse)
    assert not (tmp_path / "never").exists()


def test_study_runs_a_config_and_returns_every_job_as_a_dict(tmp_path):
    import json

    config = {
        "scenes": [{"mesh": "sphere", "material": "lambert:0.6,0.5,0.4"}],
        "models": [{"model": "rp"}, {"model": "single-mlp"}],
        "position": "uniform", "reciprocity": "exact", "size": 40, "views": 3, "train_views": 2,
        "train_lights": 3, "test_lights": 2, "sigma": 0.001, "target_median": 0.2, "seed": 0, "steps": 10,
        "batch": 512, "lr": 0.001, "lr_final": 0.0001, "pixel_stride": 2, "reciprocity_pairs": 100,
        "energy_pairs": 4, "energy_samples": 100,
    }
    path = tmp_path / "study.json"
    path.write_text(json.dumps(config))
    reports = []
    jobs = nbrdf.study(path, out=tmp_path / "out", progress=lambda done, total: reports.append((done, total)))
    assert [j["model"] for j in jobs] == ["rp", "single-mlp+exact"]
    assert all(j["eval"]["reference"] == "clean" and j["ceiling"]["psnr"] > 20 for j in jobs)
    assert (tmp_path / "out" / "REPORT.md").is_file() and reports[-1] == (10, 10)


def test_with_fitted_sampler_fits_the_proxy_as_the_trainers_export_does(fitted):
    """A fresh model samples the cosine lobe (a proxy of untrained weights would follow nothing);
    `with_fitted_sampler` fits the proxies to the present weights exactly as a fit's export did."""
    rng = np.random.default_rng(5)
    wi, wo = unit_rows(rng, 64), unit_rows(rng, 64)
    fresh = nbrdf.init_model("single-mlp", position="uniform", seed=1)
    np.testing.assert_allclose(fresh.pdf(wi, wo), wi[:, 2] / np.pi, rtol=1e-5)
    m = nbrdf.Model.load(fitted)
    again = m.with_weights(m.weights).with_fitted_sampler()
    np.testing.assert_array_equal(again.pdf(wi, wo), m.pdf(wi, wo))
    np.testing.assert_array_equal(again.eval(wi, wo), m.eval(wi, wo))


def test_weights_round_trip_and_their_gradient_by_the_trainers_backward(tmp_path):
    """A model's weights as an array, the same model with others, written and loaded again; and
    `weight_gradient`, the sum over pairs of grad · ∂f/∂w, which is linear in grad and broadcasts."""
    m = nbrdf.init_model("additive-shared", enhanced=True, position="uniform", seed=2, median=0.3)
    w = m.weights
    assert w.shape == (m.n_parameters,) and w.dtype == np.float32
    assert np.array_equal(nbrdf.init_model("additive-shared", enhanced=True, position="uniform", seed=2, median=0.3).weights, w)
    rng = np.random.default_rng(4)
    wi, wo = unit_rows(rng, 32), unit_rows(rng, 32)
    moved = m.with_weights(w * 1.01)
    assert np.array_equal(moved.weights, (w * 1.01).astype(np.float32))
    assert not np.array_equal(moved.eval(wi, wo), m.eval(wi, wo))
    moved.save(tmp_path / "moved.nbrdf")
    again = nbrdf.Model.load(tmp_path / "moved.nbrdf")
    np.testing.assert_array_equal(again.eval(wi, wo), moved.eval(wi, wo))
    # Any real dtype is accepted; the sampler (fitted to the first weights) is kept: same directions.
    u = rng.random((32, 3))
    np.testing.assert_array_equal(m.with_weights(w.astype(np.float64) * 1.01).sample(wo, u)[0], m.sample(wo, u)[0])

    g = rng.uniform(-1, 1, (32, 3))
    grad = m.weight_gradient(wi, wo, g)
    assert grad.shape == w.shape and np.abs(grad).max() > 0
    np.testing.assert_allclose(m.weight_gradient(wi, wo, 2 * g), 2 * grad, rtol=1e-5, atol=1e-7)
    # One grad row broadcast over every pair is the same as the rows repeated.
    np.testing.assert_allclose(m.weight_gradient(wi, wo, [1.0, 0.5, 0.25]),
                               m.weight_gradient(wi, wo, np.tile([1.0, 0.5, 0.25], (32, 1))), rtol=1e-6, atol=1e-9)
    # The derivative along a direction of weight space: (L(w + h d) - L(w - h d)) / 2h = grad · d.
    d = rng.normal(size=w.shape).astype(np.float32) * 1e-2
    def loss(weights):
        return float((m.with_weights(weights).eval(wi, wo).astype(np.float64) * g).sum())
    h = 0.02
    fd = (loss(w + h * d) - loss(w - h * d)) / (2 * h)
    along = float(grad.astype(np.float64) @ d.astype(np.float64))
    assert abs(fd - along) <= 0.02 * abs(fd) + 1e-6, (fd, along)

    with pytest.raises(ValueError, match=r"weights must have shape \(%d,\)" % len(w)):
        m.with_weights(w[:-1])
    with pytest.raises(ValueError, match="not a finite number"):
        m.with_weights(np.where(np.arange(len(w)) == 7, np.nan, w))
    with pytest.raises(ValueError, match="grad must have shape"):
        m.weight_gradient(wi, wo, g[:, :2])
    with pytest.raises(ValueError, match="no network weights"):
        nbrdf.lambert([0.5, 0.5, 0.5]).weights
    with pytest.raises(ValueError, match="pass points"):
        nbrdf.init_model("single-mlp", position="extrinsic:2").weight_gradient(wi, wo, g)
    with pytest.raises(ValueError, match="intrinsic"):
        nbrdf.init_model("single-mlp", position="intrinsic:8")
    with pytest.raises(ValueError, match="model: unknown model"):
        nbrdf.init_model("plastic")
