"""Array arguments follow numpy's conventions: any real dtype and any array-like, read as float32 the
way ``astype(np.float32)`` rounds (so every result equals the float32 call's bit for bit); a single
direction as well as a batch, the arguments' leading dimensions broadcast by numpy's rules; results
float32 with the broadcast leading shape; aligned float32 and float64 arrays are read without a
conversion, anything else converted once; non-numbers refused naming the argument."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import nbrdf
from conftest import need_json, unit_rows


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


@pytest.fixture(params=["builtin", "parametric", "model", "nbrdf-json"])
def brdf(request, fitted) -> nbrdf.Model:
    """One BRDF of each kind the matrix runs on (the NBRDF-json network skips without the shared data)."""
    if request.param == "builtin":
        return nbrdf.builtin("two-lobe-metal")
    if request.param == "parametric":
        return nbrdf.disney([0.6, 0.5, 0.4], metallic=0.5, roughness=0.3)
    if request.param == "model":
        return nbrdf.Model.load(fitted)
    return nbrdf.nbrdf_json(need_json())


@pytest.fixture(scope="module")
def fitted_intrinsic(tmp_path_factory) -> nbrdf.Model:
    """A Single MLP fitted for 5 steps on a tiny sphere data set, intrinsically encoded: its file
    carries the per-vertex feature table that position_features interpolates."""
    out = tmp_path_factory.mktemp("fit-intrinsic")
    data = nbrdf.synth(out / "data", material="lambert:0.6,0.5,0.4", size=24, views=2, train_views=1,
                       train_lights=2, test_lights=1, progress=False)
    fit = nbrdf.fit("single-mlp", data=data, position="intrinsic:4", steps=5, batch=256, out=out / "fit", progress=False)
    return nbrdf.Model.load(fit.model)


def float64_rows(rng: np.random.Generator, n: int) -> np.ndarray:
    """Unit directions in float64, numpy's default: most are not float32 numbers."""
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("dtype", [np.float64, np.float32, np.float16, np.longdouble])
def test_every_float_dtype_gives_the_float32_values_bit_for_bit(brdf, dtype):
    rng = np.random.default_rng(10)
    wi, wo, u = float64_rows(rng, 2000).astype(dtype), float64_rows(rng, 2000).astype(dtype), rng.random((2000, 3)).astype(dtype)
    wi32, wo32, u32 = wi.astype(np.float32), wo.astype(np.float32), u.astype(np.float32)
    f = brdf.eval(wi, wo)
    assert f.dtype == np.float32 and f.shape == (2000, 3)
    np.testing.assert_array_equal(bits(f), bits(brdf.eval(wi32, wo32)))
    np.testing.assert_array_equal(bits(brdf.pdf(wi, wo)), bits(brdf.pdf(wi32, wo32)))
    for got, want in zip(brdf.sample(wo, u), brdf.sample(wo32, u32)):
        np.testing.assert_array_equal(bits(got), bits(want))
    assert np.count_nonzero(f) > 1000  # not a matrix of zeros


@pytest.mark.parametrize("dtype", [np.int8, np.int32, np.int64, np.uint16, np.bool_])
def test_integer_and_bool_directions_are_numbers_as_numpy_reads_them(dtype):
    m = nbrdf.lambert([0.8, 0.5, 0.2])
    up = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1]], dtype)
    np.testing.assert_array_equal(m.eval(up, up[0]), m.eval(up.astype(np.float32), np.float32([0, 0, 1])))
    assert m.pdf(up[0], up[0]) == np.float32(1 / np.pi)


def test_array_likes_of_any_layout_give_the_contiguous_float32_values(brdf):
    rng = np.random.default_rng(11)
    wi, wo = unit_rows(rng, 64), unit_rows(rng, 64)
    want = bits(brdf.eval(wi, wo))
    wide = np.zeros((64, 7), np.float64)
    wide[:, 1:4], wide[:, 4:] = wi, wo
    unaligned = np.frombuffer(b"\0" + wi.tobytes(), np.float32, offset=1).reshape(64, 3)
    assert not unaligned.flags.aligned
    likes = {
        "lists": (wi.tolist(), wo.tolist()),
        "tuples": (tuple(map(tuple, wi.tolist())), tuple(map(tuple, wo.tolist()))),
        "strided float64 views": (wide[:, 1:4], wide[:, 4:]),
        "Fortran order": (np.asfortranarray(wi), np.asfortranarray(wo)),
        "negative strides": (wi[::-1][::-1], wo[::-1, ::-1][::-1, ::-1]),
        "transposed": (np.ascontiguousarray(wi.T).T, np.ascontiguousarray(wo.T).T),
        "big-endian": (wi.astype(">f4"), wo.astype(">f8")),
        "unaligned": (unaligned, wo),
        "rows of numpy scalars": ([[np.float32(x) for x in r] for r in wi], wo),
    }
    for name, (a, b) in likes.items():
        np.testing.assert_array_equal(bits(brdf.eval(a, b)), want, err_msg=name)


@pytest.mark.parametrize(
    "wi_shape, wo_shape, lead",
    [
        ((5, 3), (3,), (5,)),
        ((5, 3), (1, 3), (5,)),
        ((3,), (5, 3), (5,)),
        ((1, 3), (1, 3), (1,)),
        ((3,), (3,), ()),
        ((4, 5, 3), (3,), (4, 5)),
        ((4, 1, 3), (1, 5, 3), (4, 5)),
        ((0, 3), (3,), (0,)),
    ],
)
def test_leading_dimensions_broadcast_like_numpy(brdf, wi_shape, wo_shape, lead):
    rng = np.random.default_rng(12)
    wi = float64_rows(rng, int(np.prod(wi_shape[:-1]))).reshape(wi_shape)
    wo = float64_rows(rng, int(np.prod(wo_shape[:-1]))).reshape(wo_shape)
    # The reference: both broadcast by numpy, then evaluated as (N, 3) rows.
    a, b = (np.broadcast_to(x, lead + (3,)).reshape(-1, 3) for x in (wi, wo))
    f, p = brdf.eval(wi, wo), brdf.pdf(wi, wo)
    assert f.shape == lead + (3,) and f.dtype == np.float32
    np.testing.assert_array_equal(bits(f).reshape(-1, 3), bits(brdf.eval(a, b)))
    np.testing.assert_array_equal(bits(p).reshape(-1), bits(brdf.pdf(a, b)))
    if lead == ():
        assert isinstance(p, np.float32)  # a scalar, as numpy's functions return one value
    else:
        assert p.shape == lead and p.dtype == np.float32
    u = np.full(wo_shape, 0.25)
    s_wi, weight, pdf = brdf.sample(wo, u)
    assert s_wi.shape == weight.shape == wo_shape and np.shape(pdf) == wo_shape[:-1]
    np.testing.assert_array_equal(bits(s_wi).reshape(-1, 3), bits(brdf.sample(wo.reshape(-1, 3), u.reshape(-1, 3))[0]))


def test_a_single_query_in_the_users_float64():
    m = nbrdf.builtin("two-lobe-metal")
    wi = np.array([0.3, 0.1, 0.95]) / np.linalg.norm([0.3, 0.1, 0.95])
    wo = np.array([0.0, 0.3, 0.954])
    f = m.eval(wi, wo)
    assert f.shape == (3,) and (f > 0).all()
    np.testing.assert_array_equal(f, m.eval(wi[None].astype(np.float32), wo[None].astype(np.float32))[0])
    # One view against many lights, the common shading query.
    lights = float64_rows(np.random.default_rng(13), 100)
    np.testing.assert_array_equal(m.eval(lights, wo), m.eval(lights, np.tile(wo, (100, 1))))


def test_shapes_that_do_not_broadcast_name_both_arguments(brdf):
    with pytest.raises(ValueError, match=r"wi \(4,\), wo \(5,\) do not broadcast"):
        brdf.eval(np.zeros((4, 3)), np.zeros((5, 3)))
    with pytest.raises(ValueError, match=r"wo \(2, 4\), u \(3,\) do not broadcast"):
        brdf.sample(np.zeros((2, 4, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"wi must have shape \(3,\) or \(N, 3\).*; got float64 array of shape \(4, 2\)"):
        brdf.pdf(np.zeros((4, 2)), np.zeros(3))
    with pytest.raises(ValueError, match=r"wo must have shape .*; got float of shape \(\)"):
        brdf.eval(np.zeros(3), 1.0)


@pytest.mark.parametrize(
    "value, error, message",
    [
        ("abc", ValueError, "wo must hold real numbers; got str"),
        (["0", "0", "1"], ValueError, "wo must hold real numbers; got list of shape \\(3,\\) \\(as <U1"),
        (np.array(["0", "0", "1"]), ValueError, "wo must hold real numbers; got <U1 array"),
        ([0, 0, 1j], TypeError, "wo must hold real numbers; got list of shape \\(3,\\) \\(as complex128"),
        (np.zeros((2, 3), np.complex64), TypeError, "wo must hold real numbers; got complex64 array of shape \\(2, 3\\)"),
        ([object(), 0, 1], TypeError, "wo must hold real numbers; got list of shape \\(3,\\) \\(as object"),
        ([0, 0, None], TypeError, "wo must hold real numbers"),
        (np.zeros(3, "datetime64[s]"), TypeError, "wo must hold real numbers"),
        ([[0, 0, 1], [0, 1]], ValueError, "wo: setting an array element with a sequence"),
    ],
)
def test_non_numbers_are_refused_naming_the_argument(value, error, message):
    with pytest.raises(error, match=message):
        nbrdf.lambert([0.5] * 3).eval([0.0, 0.0, 1.0], value)


def numpy_bytes_allocated(call) -> int:
    """Peak bytes numpy and Python allocate during ``call()`` (tracemalloc sees numpy's buffers, not
    the extension's own Rust allocations: its copy of the inputs and its results)."""
    tracemalloc.start()
    try:
        call()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_aligned_float32_and_float64_are_read_in_place_anything_else_converted_once():
    m = nbrdf.lambert([0.5] * 3)
    n = 100_000
    wi = float64_rows(np.random.default_rng(14), n)
    one = n * 3 * 4  # one float32 conversion of an (n, 3) argument
    for name, x in [
        ("C-contiguous float32", wi.astype(np.float32)),
        ("float64", wi),
        ("strided float32", np.tile(wi.astype(np.float32), 2)[:, 1:4]),
        ("reversed float64", wi[::-1]),
    ]:
        assert numpy_bytes_allocated(lambda: m.eval(x, x[0])) < one / 20, name
    for name, x in [("float16", wi.astype(np.float16)), ("int32", (wi * 10).astype(np.int32)), ("big-endian", wi.astype(">f4"))]:
        assert one <= numpy_bytes_allocated(lambda: m.eval(x, wi[0])) < 1.2 * one, name


def test_points_take_any_real_dtype_and_broadcast_with_the_directions(fitted_extrinsic):
    m = nbrdf.Model.load(fitted_extrinsic)
    rng = np.random.default_rng(15)
    wi, wo = float64_rows(rng, 40), float64_rows(rng, 40)
    p = rng.uniform(-1, 1, (40, 3))
    per_pair = m.eval(wi, wo, p)
    np.testing.assert_array_equal(per_pair, m.eval(wi.astype(np.float32), wo.astype(np.float32), p.astype(np.float32)))
    # One point as (3,), (1, 3) or a list: the same BRDF for every pair.
    one = m.eval(wi, wo, p[7].astype(np.float32))
    for like in [p[7], p[7:8], p[7].tolist()]:
        np.testing.assert_array_equal(m.eval(wi, wo, like), one)
    np.testing.assert_array_equal(one[7], per_pair[7])
    # One direction pair at every point: the pair broadcasts over the points.
    np.testing.assert_array_equal(m.eval(wi[3], wo[3], p), m.eval(np.tile(wi[3], (40, 1)), np.tile(wo[3], (40, 1)), p))
    with pytest.raises(ValueError, match=r"points must hold real numbers"):
        m.eval(wi, wo, ["a", "b", "c"])


def test_position_features_take_any_integers_and_broadcast(fitted_intrinsic):
    m = fitted_intrinsic
    assert m.has_position_table
    tri = nbrdf.mesh("sphere")[2][:20]
    bary = np.random.default_rng(16).dirichlet([1, 1, 1], 20)
    want = m.position_features(tri, bary.astype(np.float32))
    assert want.shape == (20, m.position_len) and want.dtype == np.float32
    np.testing.assert_array_equal(m.position_features(tri.astype(np.int64), bary), want)
    np.testing.assert_array_equal(m.position_features(tri.tolist(), bary.tolist()), want)
    # One triangle at many barycentric points, and one point of one triangle.
    np.testing.assert_array_equal(m.position_features(tri[4], bary), m.position_features(np.tile(tri[4], (20, 1)), bary))
    assert m.position_features(tri[4], bary[4]).shape == (m.position_len,)
    # The features go straight into points.
    assert m.eval([0, 0, 1.0], [0, 0.6, 0.8], want).shape == (20, 3)
    with pytest.raises(TypeError, match="triangles must hold integers; got float64"):
        m.position_features(tri.astype(np.float64), bary)
    with pytest.raises(ValueError, match="triangles: index -1 is negative or too large"):
        m.position_features(np.array([[0, 1, -1]]), bary[:1])


def test_metrics_take_any_real_dtype_and_array_like():
    img = nbrdf.render(nbrdf.lambert([0.5] * 3), width=36, height=32, env_color=[1, 1, 1], spp=2)[0]
    brighter = img * 1.3
    want = nbrdf.compare(img, brighter)
    for name, (r, t) in {"float64": (img.astype(np.float64), brighter.astype(np.float64)), "lists": (img.tolist(), brighter.tolist())}.items():
        assert nbrdf.compare(r, t) == want, name
    mask = img[..., 0] > 0.01
    assert nbrdf.compare(img, brighter, mask.tolist()) == nbrdf.compare(img, brighter, mask)
    with pytest.raises(TypeError, match="mask must hold booleans; got float64 array"):
        nbrdf.compare(img, brighter, mask.astype(np.float64))
    with pytest.raises(ValueError, match=r"test must have shape \(H, W, 3\).*; got float32 array of shape \(32, 36\)"):
        nbrdf.compare(img, brighter[..., 0])

    pred = np.full((10, 3), 0.5)
    keep = np.arange(10) < 5
    rmse, used = nbrdf.brdf_rmse(pred, pred * 8, keep)
    assert used == 5 and abs(rmse - 0.5 ** (1 / 3)) < 1e-6
    # The reference broadcasts over the rows, as keep does.
    assert nbrdf.brdf_rmse(pred.astype(np.float32), [4.0, 4.0, 4.0], keep.tolist()) == (rmse, used)
    with pytest.raises(ValueError, match=r"predicted \(10,\), reference \(10,\), keep \(4,\) do not broadcast"):
        nbrdf.brdf_rmse(pred, pred, keep[:4])


def test_render_takes_vectors_and_lights_as_array_likes():
    m = nbrdf.lambert([0.5] * 3)
    common = dict(width=12, height=10, spp=2)
    want = nbrdf.render(m, eye=[0.0, 0.6, 3.4], lights=[([0.0, 0.0, 1.0], [1.0, 1.0, 1.0])], **common)[0]
    got = nbrdf.render(m, eye=np.array([0, 0.6, 3.4]), target=np.zeros(3, np.float16), up=(0, 1, 0),
                       lights=np.array([[[0, 0, 1], [1, 1, 1]]]), **common)[0]
    np.testing.assert_array_equal(got, want)
    with pytest.raises(ValueError, match=r"eye must have shape \(3,\); got list of shape \(2,\)"):
        nbrdf.render(m, eye=[0, 1], env_color=[1, 1, 1], **common)
    with pytest.raises(ValueError, match=r"lights must have shape \(L, 2, 3\)"):
        nbrdf.render(m, lights=[[0, 0, 1]], **common)
    with pytest.raises(ValueError, match="env_color must hold real numbers"):
        nbrdf.render(m, env_color="white", **common)
