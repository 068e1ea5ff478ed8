"""The package's values are the Rust API's bit for bit (eval, pdf and sample, at per-pair points and
at one point, in batches split across threads), and an NBRDF-json network written out in numpy
agrees with the package's evaluation."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nbrdf
from conftest import need_json, unit_rows


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def test_values_equal_the_rust_api_bit_for_bit(reference_values):
    for spec, ref in reference_values:
        brdf = nbrdf.from_spec(spec)
        k = ref["k"]
        assert brdf.position_len == k, spec
        points = ref["points"] if k else None
        np.testing.assert_array_equal(bits(brdf.eval(ref["wi"], ref["wo"], points)), bits(ref["eval"]), err_msg=spec)
        np.testing.assert_array_equal(bits(brdf.pdf(ref["wi"], ref["wo"], points)), bits(ref["pdf"]), err_msg=spec)
        wi, weight, pdf = brdf.sample(ref["wo"], ref["u"], points)
        np.testing.assert_array_equal(bits(wi), bits(ref["sample_wi"]), err_msg=spec)
        np.testing.assert_array_equal(bits(weight), bits(ref["sample_weight"]), err_msg=spec)
        np.testing.assert_array_equal(bits(pdf), bits(ref["sample_pdf"]), err_msg=spec)
        # Every pair at point 0: for models, the batched path (Model::eval_many).
        p0 = ref["points"][0] if k else None
        np.testing.assert_array_equal(bits(brdf.eval(ref["wi"], ref["wo"], p0)), bits(ref["eval_at_point0"]), err_msg=spec)
        # The fixture is not degenerate: values, densities and samples were produced.
        assert np.count_nonzero(ref["eval"]) > len(ref["eval"]) and np.count_nonzero(ref["sample_pdf"]) > len(pdf) // 2, spec


def test_strided_and_batched_inputs_give_the_values_of_contiguous_ones(fitted):
    m = nbrdf.Model.load(fitted)
    rng = np.random.default_rng(3)
    wi, wo = unit_rows(rng, 5000), unit_rows(rng, 5000)
    whole = m.eval(wi, wo)
    # A strided view (every other row of a wider array) and single rows give the same bits.
    wide = np.zeros((10000, 6), np.float32)
    wide[::2, :3], wide[::2, 3:] = wi, wo
    np.testing.assert_array_equal(bits(m.eval(wide[::2, :3], wide[::2, 3:])), bits(whole))
    for i in [0, 1, 1023, 1024, 4999]:
        np.testing.assert_array_equal(bits(m.eval(wi[i:i + 1], wo[i:i + 1])[0]), bits(whole[i]))


def reference_forward(path, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """The NBRDF-json forward pass of ../shared/data/README.md in float64 numpy: the half vector
    rotated to φh = 0, the difference vector (wi in the half vector's frame), the layers, then
    max(exp(y) - 1, 0)."""
    net = json.loads(path.read_text())
    wi, wo = wi.astype(np.float64), wo.astype(np.float64)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    theta_h = np.arccos(np.clip(h[:, 2], -1, 1))
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    # d = R_y(-θh) R_z(-φh) wi
    c, s = np.cos(-phi_h), np.sin(-phi_h)
    x, y, z = c * wi[:, 0] - s * wi[:, 1], s * wi[:, 0] + c * wi[:, 1], wi[:, 2]
    c, s = np.cos(-theta_h), np.sin(-theta_h)
    d = np.stack([c * x + s * z, y, -s * x + c * z], axis=1)
    x = np.concatenate([np.stack([np.sin(theta_h), np.zeros_like(theta_h), np.cos(theta_h)], axis=1), d], axis=1)
    for layer in net["layers"]:
        x = x @ np.asarray(layer["weight"], np.float64).T + np.asarray(layer["bias"], np.float64)
        if layer["activation"] == "relu":
            x = np.maximum(x, 0.0)
    return np.maximum(np.expm1(x), 0.0)


@pytest.mark.parametrize("name", ["gold-metallic-paint", "chrome-steel"])
def test_nbrdf_json_agrees_with_a_numpy_forward_pass(name):
    """To 1e-6 (relative above 1, absolute below) on 99.9% of random pairs; within 1e-5 on the rest,
    where float32's wi + wo nearly cancels (the half vector of almost opposite azimuths) and the
    package's float32 input transform is off by a few ulps of the cancelled sum."""
    path = need_json(name)
    m = nbrdf.nbrdf_json(path)
    rng = np.random.default_rng(7)
    wi, wo = unit_rows(rng, 20000), unit_rows(rng, 20000)
    # Away from grazing angles, where the f32 directions themselves are the larger error.
    keep = (wi[:, 2] > 0.05) & (wo[:, 2] > 0.05)
    wi, wo = wi[keep], wo[keep]
    got = m.eval(wi, wo).astype(np.float64)
    want = reference_forward(path, wi, wo)
    err = (np.abs(got - want) / np.maximum(1.0, want)).max(axis=1)
    assert np.quantile(err, 0.999) <= 1e-6, np.quantile(err, [0.5, 0.99, 0.999])
    assert err.max() <= 1e-5, err.max()
    assert want.max() > 1.0  # a real material, not a network of zeros
