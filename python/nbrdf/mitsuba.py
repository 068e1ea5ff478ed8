"""nbrdf.mitsuba: nbrdf's BRDFs as a Mitsuba 3 BSDF, ``"nbrdf"``, for the ``*_rgb`` variants.

Importing the module registers the plugin for the variant that is set; after ``mi.set_variant`` to
another one, call ``register()`` again. Scene parameters:

- ``filename``: a fitted ``.nbrdf`` model, an NBRDF-json ``.json`` network or a MERL ``.binary``
  table; or instead ``spec``: anything ``nbrdf.from_spec`` takes (``"lambert:0.5,0.5,0.5"``,
  ``"disney:..."``, ``"builtin:velvet"``, ...).
- ``position`` (models that vary over the surface): ``"p"`` (the default) feeds the hit point
  ``si.p``, mapped by ``position_transform`` (a 4×4 transform, default identity: the frame the model
  was fitted in, e.g. the data set's unit-sphere normalisation) to an extrinsically encoded model; a
  texture instead gives the three values per hit itself.

Conventions: Mitsuba's ``si.wi`` points toward the viewer (nbrdf's ``wo``) and its ``wo`` toward the
light (nbrdf's ``wi``); Mitsuba's ``eval`` includes the cosine of the light direction, nbrdf's values
do not, so ``eval`` multiplies it in. ``sample`` draws from nbrdf's own sampler (a parametric model's
lobes, the fitted proxy of a neural model, MERL table or NBRDF-json network) with ``sample2`` placing
the direction and ``sample1`` picking the lobe; its weight is ``f cos / pdf`` and ``pdf`` the proxy's
own density, so estimates stay unbiased.

- ``differentiable`` (default false; ``*_ad_rgb`` variants and fitted ``.nbrdf`` network models): the
  model's weights become the scene parameter ``weights`` (``mi.traverse``, flagged differentiable),
  and the values of ``eval``, ``eval_pdf`` and ``sample``'s weight carry gradients to them. Each is
  a Dr.Jit custom operation: the forward value is the core's ``eval`` and the backward pass hands
  ``∂L/∂f`` to the trainer's backward (``Model.weight_gradient``), so no network is re-implemented in
  Dr.Jit. Reverse mode only (``dr.backward``, the ``prb`` integrators' adjoint pass). The sampler stays
  the one fitted to the loaded weights: it remains a valid density, so estimates stay unbiased as the
  weights move, only less efficient. An energy-bounded model is refused (its bound belongs to the
  loaded weights); ``Model.with_weights`` gives the unbounded model to start from. Write the result
  with ``bsdf.model.save(path)``.

Every method hands the whole wavefront to one batched call of the Rust library through numpy. In the
JIT variants (``llvm_ad_rgb``, ``cuda_ad_rgb``) that means the arrays must be evaluated, which a
symbolic (recorded) loop, virtual call or conditional cannot do: ``register()`` therefore turns
``dr.JitFlag.SymbolicLoops``, ``SymbolicCalls`` and ``SymbolicConditionals`` off (evaluated mode;
pass ``evaluated=False`` to leave them). Without ``differentiable`` the values are plain arrays outside
Dr.Jit's AD graph. In ``scalar_rgb`` each call is one direction pair, about 10-30 µs of Python per
call; the JIT variants pay that per wavefront.
"""

from __future__ import annotations

from typing import Any, Dict, Optional

import drjit as dr
import mitsuba as mi
import numpy as np

from . import Model, from_spec

__all__ = ["register", "shape", "PLUGIN"]

#: The plugin's name in scene descriptions.
PLUGIN = "nbrdf"

_classes: Dict[str, type] = {}


def _width(*values: Any) -> int:
    return max(dr.width(v) for v in values)


def _rows3(v: Any, n: int) -> np.ndarray:
    """A Dr.Jit 3-vector (scalar or of any width that broadcasts to n) as (n, 3) float32."""
    a = np.asarray(v, dtype=np.float32)
    if a.ndim == 1:
        a = a[:, None]
    return np.ascontiguousarray(np.broadcast_to(a, (3, n)).T)


def _flat(v: Any, n: int, dtype: Any = np.float32) -> np.ndarray:
    """A Dr.Jit scalar array (or a Python scalar) broadcast to n values."""
    return np.broadcast_to(np.asarray(v, dtype=dtype).reshape(-1), (n,))


def _has(props: "mi.Properties", key: str) -> bool:
    """Whether the scene gave the property (``in`` since Mitsuba 3.6, ``has_property`` before)."""
    try:
        return key in props
    except TypeError:
        return props.has_property(key)


class _Query:
    """One call's inputs and value, kept for the backward pass of its custom operation (a plain
    object: Dr.Jit passes it through untouched)."""

    def __init__(self, model: Model, value: np.ndarray, scale: np.ndarray, wi: np.ndarray, wo: np.ndarray,
                 points: Optional[np.ndarray], act: np.ndarray) -> None:
        self.model, self.value, self.scale = model, value, np.asarray(scale, dtype=np.float32)
        self.wi, self.wo, self.points, self.act = wi, wo, points, np.asarray(act, dtype=bool)


def _make_class() -> type:
    """The BSDF class of the variant that is set: Mitsuba's base class and types differ per variant."""
    scalar = (mi.variant() or "").startswith("scalar")

    def color(rows: np.ndarray) -> Any:
        return mi.Color3f(*(float(x) for x in rows[0])) if scalar else mi.Color3f(np.ascontiguousarray(rows.T))

    def vector(rows: np.ndarray) -> Any:
        return mi.Vector3f(*(float(x) for x in rows[0])) if scalar else mi.Vector3f(np.ascontiguousarray(rows.T))

    def floats(values: np.ndarray) -> Any:
        return float(values[0]) if scalar else mi.Float(np.ascontiguousarray(values, dtype=np.float32))

    class Weighted(dr.CustomOp):
        """``f(weights) · scale`` per pair as a Dr.Jit operation: the value was computed by the core;
        the backward pass turns ``∂L/∂(f · scale)`` into ``∂L/∂weights`` by the trainer's backward."""

        def eval(self, weights: Any, q: "_Query") -> Any:
            self.q = q
            return color(q.value)

        def forward(self) -> None:
            raise NotImplementedError("the nbrdf BSDF differentiates in reverse mode only (dr.backward, prb)")

        def backward(self) -> None:
            q = self.q
            g = np.asarray(self.grad_out(), dtype=np.float32).reshape(3, -1).T
            g = np.ascontiguousarray(np.broadcast_to(g, (len(q.scale), 3)) * q.scale[:, None])
            g[~q.act] = 0.0
            # Only the pairs that carry a derivative (misses, inactive lanes and zero cotangents do not).
            keep = np.flatnonzero(np.any(g != 0.0, axis=1))
            wi, wo = np.broadcast_to(q.wi, g.shape)[keep], np.broadcast_to(q.wo, g.shape)[keep]
            points = None if q.points is None else np.broadcast_to(q.points, (len(g), q.points.shape[-1]))[keep]
            grad = q.model.weight_gradient(wi, wo, g[keep], points) if len(keep) else np.zeros(q.model.n_parameters, np.float32)
            self.set_grad_in("weights", mi.Float(grad))

        def name(self) -> str:
            return "nbrdf weights"

    class NbrdfBSDF(mi.BSDF):
        """A BRDF of nbrdf (see the module's documentation for the parameters)."""

        def __init__(self, props: "mi.Properties") -> None:
            mi.BSDF.__init__(self, props)
            if _has(props, "filename"):
                self.source = str(props["filename"])
                self.model = Model.load(self.source)
            elif _has(props, "spec"):
                self.source = str(props["spec"])
                self.model = from_spec(self.source)
            else:
                raise ValueError('the "nbrdf" BSDF needs a "filename" (.nbrdf, .json, .binary) or a "spec"')
            self.position: Any = props["position"] if _has(props, "position") else "p"
            # As a 4×4 numpy matrix: the property is a scalar (double) transform in every variant.
            self.to_model: Optional[np.ndarray] = (
                np.asarray(getattr(props["position_transform"], "matrix"), dtype=np.float64).reshape(4, 4)
                if _has(props, "position_transform")
                else None
            )
            k = self.model.position_len
            if k > 0 and (k != 3 or self.model.has_position_table):
                raise ValueError(
                    f"{self.source}: an intrinsically encoded model ({k} features per point) needs the "
                    "fitted mesh's per-vertex table, which Mitsuba does not pass to a BSDF; evaluate it with "
                    "nbrdf.Model.position_features and eval(..., points=...) instead"
                )
            if k == 3 and isinstance(self.position, str) and self.position != "p":
                raise ValueError(f'position must be "p" or a texture, not {self.position!r}')
            self.differentiable = bool(props["differentiable"]) if _has(props, "differentiable") else False
            if self.differentiable:
                if scalar or "_ad_" not in (mi.variant() or ""):
                    raise ValueError(f"differentiable needs an *_ad_rgb variant (llvm_ad_rgb, cuda_ad_rgb), not {mi.variant()}")
                if self.model.albedo_bound is not None:
                    raise ValueError(
                        f"{self.source}: an energy-bounded model cannot be differentiated (its bound belongs to "
                        "the loaded weights); save model.with_weights(model.weights), which drops it, and bound "
                        "the optimised model afterwards (trainer bound)"
                    )
                # A ValueError naming the problem for BRDFs without trainer networks.
                self.weights = mi.Float(self.model.weights)
            # Lambert is diffuse for Mitsuba's purposes; everything else a glossy lobe (NEE and BSDF
            # sampling both apply to either).
            diffuse = self.model.parametric_kind == "lambert"
            self.lobe = mi.BSDFFlags.DiffuseReflection if diffuse else mi.BSDFFlags.GlossyReflection
            self.m_flags = self.lobe | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]

        def _points(self, si: Any, n: int, active: Any) -> Optional[np.ndarray]:
            if self.model.position_len == 0:
                return None
            if not isinstance(self.position, str):
                return _rows3(self.position.eval(si, active), n)
            p = _rows3(si.p, n)
            if self.to_model is not None:
                m = self.to_model
                p = (p.astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
            return p

        def _inputs(self, si: Any, wo: Any, active: Any):
            """(n, nbrdf's wi = Mitsuba's wo, nbrdf's wo = Mitsuba's si.wi, points, active) as numpy."""
            if not scalar:
                if dr.flag(dr.JitFlag.SymbolicScope):
                    raise RuntimeError(
                        "the nbrdf BSDF was called inside a symbolic loop or call; it needs evaluated ones: "
                        "call nbrdf.mitsuba.register() after mi.set_variant (it turns JitFlag.SymbolicLoops "
                        "and SymbolicCalls off)"
                    )
                dr.eval(si, wo, active)
            n = _width(si.wi, wo, active)
            return n, _rows3(wo, n), _rows3(si.wi, n), self._points(si, n, active), _flat(active, n, bool)

        def _enabled(self, ctx: Any) -> bool:
            return bool(ctx.is_enabled(self.lobe, 0))

        def _value(self, value: np.ndarray, scale: np.ndarray, wi: np.ndarray, wo: np.ndarray,
                   points: Optional[np.ndarray], act: np.ndarray) -> Any:
            """``value`` (f · scale, inactive rows zero) as a Color3f, differentiable in the weights
            where they take gradients."""
            if not (self.differentiable and dr.grad_enabled(self.weights)):
                return color(value)
            q = _Query(self.model, value, scale, wi, wo, points, act)
            return dr.custom(Weighted, self.weights, q)

        def eval(self, ctx, si, wo, active=True):
            n, wi_nb, wo_nb, points, act = self._inputs(si, wo, active)
            f = self.model.eval(wi_nb, wo_nb, points) if self._enabled(ctx) else np.zeros((n, 3), np.float32)
            # Mitsuba's eval carries the cosine foreshortening of the light direction; nbrdf's does not.
            cos = np.maximum(wi_nb[:, 2], 0.0)
            f *= cos[:, None]
            f[~act] = 0.0
            return self._value(f, cos, wi_nb, wo_nb, points, act)

        def pdf(self, ctx, si, wo, active=True):
            n, wi_nb, wo_nb, points, act = self._inputs(si, wo, active)
            p = self.model.pdf(wi_nb, wo_nb, points) if self._enabled(ctx) else np.zeros(n, np.float32)
            p[~act] = 0.0
            return floats(p)

        def eval_pdf(self, ctx, si, wo, active=True):
            n, wi_nb, wo_nb, points, act = self._inputs(si, wo, active)
            if self._enabled(ctx):
                f, p = self.model.eval(wi_nb, wo_nb, points), self.model.pdf(wi_nb, wo_nb, points)
            else:
                f, p = np.zeros((n, 3), np.float32), np.zeros(n, np.float32)
            cos = np.maximum(wi_nb[:, 2], 0.0)
            f *= cos[:, None]
            f[~act], p[~act] = 0.0, 0.0
            return self._value(f, cos, wi_nb, wo_nb, points, act), floats(p)

        def sample(self, ctx, si, sample1, sample2, active=True):
            if not scalar:
                dr.eval(sample1, sample2)
            n, _, wo_nb, points, act = self._inputs(si, si.wi, active)
            n = max(n, _width(sample1, sample2))
            wo_nb = np.ascontiguousarray(np.broadcast_to(wo_nb, (n, 3)))
            if points is not None:
                points = np.ascontiguousarray(np.broadcast_to(points, (n, 3)))
            act = np.broadcast_to(act, (n,))
            u2 = np.asarray(sample2, dtype=np.float32).reshape(2, -1)
            u = np.stack([_flat(u2[0], n), _flat(u2[1], n), _flat(sample1, n)], axis=1)
            if self._enabled(ctx):
                wi, weight, pdf = self.model.sample(wo_nb, u, points)
            else:
                wi, weight, pdf = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32), np.zeros(n, np.float32)
            none = ~act | (pdf <= 0.0)
            wi[none], weight[none], pdf[none] = 0.0, 0.0, 0.0
            # The weight f cos / pdf: differentiable in f, the density held fixed.
            scale = np.where(none, 0.0, np.maximum(wi[:, 2], 0.0) / np.where(none, 1.0, pdf)).astype(np.float32)
            bs = mi.BSDFSample3f() if scalar else dr.zeros(mi.BSDFSample3f, n)
            bs.wo = vector(wi)
            bs.pdf = floats(pdf)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+self.lobe)
            bs.sampled_component = mi.UInt32(0)
            return bs, self._value(weight, scale, wi, wo_nb, points, ~none)

        def traverse(self, callback):
            # Only the weights of a differentiable model; everything else lives in the Rust library.
            if self.differentiable:
                put = getattr(callback, "put", None) or callback.put_parameter
                put("weights", self.weights, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys):
            if self.differentiable and "weights" in keys:
                self.model = self.model.with_weights(np.asarray(self.weights, dtype=np.float32))

        def to_string(self):
            return f"NbrdfBSDF[{self.model!r}, position_len={self.model.position_len}]"

    return NbrdfBSDF


def write_ply(path: str, vertices: np.ndarray, normals: np.ndarray, triangles: np.ndarray) -> None:
    """A binary PLY with vertex normals (which Mitsuba interpolates, as nbrdf's renderer does)."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(triangles)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    faces = np.zeros(len(triangles), dtype=[("n", "u1"), ("v", "<i4", 3)])
    faces["n"], faces["v"] = 3, triangles
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.hstack([vertices, normals]).astype("<f4").tobytes())
        f.write(faces.tobytes())


def shape(mesh: str, ply: str, bsdf: Optional[dict] = None) -> dict:
    """A Mitsuba shape of the geometry ``nbrdf.render`` draws for ``mesh`` ("sphere", "torus",
    "grooved" or an OBJ/PLY file scaled into the unit sphere, the frame the data sets are made in),
    written to the PLY file ``ply``; ``bsdf`` is its material's dictionary."""
    from . import mesh as nbrdf_mesh

    write_ply(ply, *nbrdf_mesh(mesh))
    d: dict = {"type": "ply", "filename": str(ply), "face_normals": False}
    if bsdf is not None:
        d["bsdf"] = bsdf
    return d


def register(evaluated: bool = True) -> None:
    """Registers the ``"nbrdf"`` BSDF for the Mitsuba variant that is set (an ``*_rgb`` one). In a JIT
    variant, ``evaluated`` turns Dr.Jit's symbolic loops, calls and conditionals off, which the plugin's batched
    calls through numpy need (see the module's documentation)."""
    variant = mi.variant()
    if variant is None:
        raise RuntimeError("set a Mitsuba variant first, e.g. mi.set_variant('llvm_ad_rgb')")
    if not variant.endswith("_rgb"):
        raise ValueError(f"the nbrdf BSDF returns RGB values and needs an *_rgb variant, not {variant}")
    if evaluated and not variant.startswith("scalar"):
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)
        # The prb integrators' adjoint pass also runs conditionals around BSDF calls.
        dr.set_flag(dr.JitFlag.SymbolicConditionals, False)
    if variant not in _classes:
        _classes[variant] = _make_class()
    cls = _classes[variant]
    mi.register_bsdf(PLUGIN, lambda props: cls(props))


if (mi.variant() or "").endswith("_rgb"):
    register()
