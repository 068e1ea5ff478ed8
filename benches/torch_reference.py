#!/usr/bin/env python3
"""PyTorch twin of `trainer bench-step`: one training step (forward, backward, Adam) of each nbrdf
architecture, for the side-by-side comparison of docs/speed.md.

The architectures are not transcribed here: `trainer bench-step --torch` writes them (layer sizes in
file order, ReLU count, skip layer, what each network reads, the output head) to a JSON spec that this
script reads, so both sides build identical networks. Run through the trainer it serves one
architecture per request (`--serve`, interleaved with our own timing); run alone it times every
architecture of a spec and prints JSON:

    trainer bench-step --torch                       # side by side, prints the ratio
    python3 benches/torch_reference.py spec.json     # PyTorch alone
    python3 benches/torch_reference.py spec.json --check   # the parametric transcription only

What one step is, as in trainer/src/train.rs `objective` and models/mod.rs `Model::forward`:
  * networks: nn.Linear layers with ReLU after the first `hidden`, `cat([h, x])` into layer `skip`;
  * head: softplus of the single MLP's output; additive: f = sigmoid(d)/pi + softplus(s[:, :3]),
    enhanced (Eq. 8): f = (1 - sigmoid(s[:, 3:6])) * f_d + f_s plus the Sec. 4.4 L1 regularisers;
    parametric: the same parameter network, its raw outputs through the model's real formula
    (`brdf_models` below: the core's `from_raw` activations and `eval`, transcribed into plain
    vectorised torch ops differentiated by autograd; FMBRDF's per-object normalisation is an
    nn.Parameter), at random upper-hemisphere directions wi, wo;
  * loss (Eq. 9/10): mean over 3N of (srgb(clamp(f * valid * incident, 0, 1)) - target)^2;
  * optimiser: torch.optim.Adam with PyTorch's defaults and the trainer's lr.
Inputs are random with the encoded widths; timing does not depend on their values beyond the ReLU
pattern (the formulas' branches are `torch.where`s that evaluate both sides).

The transcription cannot read the Rust source, so the spec carries for each parametric model a few
check samples (raw values, object values, wi, wo and the core's f). Before timing a parametric model
the script evaluates its transcription on them in float64 and, if any value differs by more than
1e-4 relative + 1e-6 absolute, replies {"error": ...} naming the sample instead of a time.
`--check` runs only that check for every parametric model of the spec (the trainer's tests do).
Requires `pip install torch` (any 2.x, the CPU build suffices).
"""

import argparse
import json
import math
import sys
import time

SRGB_KNEE = 0.0031308


def reply(obj):
    print(json.dumps(obj), flush=True)


def build(torch, arch, batch):
    nn = torch.nn

    class Net(nn.Module):
        def __init__(self, spec):
            super().__init__()
            self.layers = nn.ModuleList(nn.Linear(i, o) for i, o in spec["layers"])
            self.hidden = spec["hidden"]
            self.skip = spec["skip"]
            self.input = spec["input"]

        def forward(self, x):
            h = x
            for l, lin in enumerate(self.layers):
                skip = 0 < l < self.hidden and self.skip >= 1 and l == self.skip and x.shape[1] > 0
                h = lin(torch.cat([h, x], 1) if skip else h)
                if l < self.hidden:
                    h = torch.relu(h)
            return h

    nets = nn.ModuleList(Net(s) for s in arch["nets"])
    inputs = {k: torch.rand(batch, w) for k, w in arch["widths"].items()}
    if arch["head"] == "parametric":  # the formula's directions: uniform on the upper hemisphere
        for k in ("wi", "wo"):
            d = torch.nn.functional.normalize(torch.randn(batch, 3), dim=1)
            inputs[k] = torch.cat([d[:, :2], d[:, 2:].abs()], 1)
    valid = torch.ones(batch, 1)
    incident = torch.rand(batch, 3)
    target = torch.rand(batch, 3)
    return nets, inputs, valid, incident, target


def gamma(torch, x):
    c = x.clamp(0.0, 1.0)
    curve = 1.055 * c.clamp_min(SRGB_KNEE).pow(1.0 / 2.4) - 0.055
    return torch.where(c > SRGB_KNEE, curve, 12.92 * c)


# The core's parametric models (src/parametric/), transcribed: each helper is the Rust function of the
# same name in the file its comment names, each model the `from_raw` table at the top of its file
# followed by its `eval`. raw: [N, n_raw] pre-activations, obj: [..., n_object] per-object raw
# parameters, wi/wo: [N, 3]; each model returns f: [N, 3].
ALPHA_MIN = 1e-3  # microfacet.rs ALPHA_MIN
CHECK_RTOL, CHECK_ATOL = 1e-4, 1e-6


def brdf_models(torch):
    """{ParametricKind::id(): f(raw, obj, wi, wo)} for every parametric model of the core."""
    F = torch.nn.functional
    INV_PI = 1.0 / math.pi
    sigmoid = torch.sigmoid

    def raw_at(raw):  # mod.rs raw_at: non-finite raw values read as 0
        return torch.where(raw.isfinite(), raw, 0.0)

    def lerp(a, b, t):  # math.rs lerp
        return a + t * (b - a)

    def clamp_alpha(alpha):  # microfacet.rs clamp_alpha (its NaN case cannot arise from a sigmoid)
        return alpha.clamp(ALPHA_MIN, 1.0)

    class HalfGeometry:  # microfacet.rs HalfGeometry::new, gated by angles.rs upper_hemisphere_pair
        def __init__(self, wi, wo):
            self.wi, self.wo = F.normalize(wi, dim=1), F.normalize(wo, dim=1)
            s = self.wi + self.wo
            s_len = s.norm(dim=1)
            h = s / s_len[:, None]
            # NaN compares false, so non-finite directions fail the gate too.
            self.ok = (self.wi[:, 2] > 0) & (self.wo[:, 2] > 0) & (s_len > 0)
            self.cos_i, self.cos_o, self.cos_h = self.wi[:, 2], self.wo[:, 2], h[:, 2]
            self.sin2_h = h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1]
            self.cos_d = (0.5 * s_len).clamp_max(1.0)

    def finish(g, f):  # every eval: 0 below the horizon, then math.rs sanitize
        return torch.where(g.ok[:, None] & f.isfinite() & (f > 0), f, 0.0)

    def beckmann_d(g, alpha):  # microfacet.rs beckmann_d
        c2, a2 = g.cos_h * g.cos_h, alpha * alpha
        c4 = c2 * c2
        return torch.where(c4 > 0, torch.exp(-g.sin2_h / (c2 * a2)) / (math.pi * a2 * c4), 0.0)

    def ggx_d(g, alpha):  # microfacet.rs ggx_d
        a2 = alpha * alpha
        t = a2 * g.cos_h * g.cos_h + g.sin2_h
        return a2 * INV_PI / (t * t)

    def gtr1_d(g, alpha):  # microfacet.rs gtr1_d; Disney's clearcoat α ≤ 0.1 never takes its α ≥ 1 branch
        a2 = alpha * alpha
        t = a2 * g.cos_h * g.cos_h + g.sin2_h
        return (a2 - 1.0) * INV_PI / (torch.log(a2) * t)

    def smith_ggx_g1_over_2cos(cos_v, alpha):  # microfacet.rs
        c2 = cos_v * cos_v
        return 1.0 / (cos_v + (alpha * alpha * (1.0 - c2) + c2).clamp_min(0.0).sqrt())

    def v_cavity_g_over_4cos(g):  # microfacet.rs
        a = 1.0 / (4.0 * g.cos_i * g.cos_o)
        k = g.cos_h / (2.0 * g.cos_d)
        return torch.minimum(torch.minimum(a, k / g.cos_i), k / g.cos_o)

    def schlick_weight(cos):  # microfacet.rs
        m = (1.0 - cos).clamp(0.0, 1.0)
        m2 = m * m
        return m2 * m2 * m

    def fresnel_schlick(f0, cos_d):  # microfacet.rs
        return f0 + (1.0 - f0) * schlick_weight(cos_d)

    def fresnel_dielectric(cos, eta):  # microfacet.rs
        c = cos.clamp(0.0, 1.0)
        sin2_t = (1.0 - c * c) / (eta * eta)
        cos_t = (1.0 - sin2_t).clamp_min(0.0).sqrt()
        r_par = (eta * c - cos_t) / (eta * c + cos_t)
        r_perp = (c - eta * cos_t) / (c + eta * cos_t)
        f = 0.5 * (r_par * r_par + r_perp * r_perp)
        f = torch.where(f.isfinite(), f.clamp(0.0, 1.0), 1.0)
        return torch.where(sin2_t >= 1.0, 1.0, f)  # total internal reflection

    def lambert(raw, obj, wi, wo):  # lambert.rs
        g = HalfGeometry(wi, wo)
        kd = sigmoid(raw_at(raw)[:, 0:3])
        return finish(g, kd * INV_PI)

    def phong(raw, obj, wi, wo):  # phong.rs
        g, r = HalfGeometry(wi, wo), raw_at(raw)
        kd = sigmoid(r[:, 0:3])
        ks = (1.0 - kd) * sigmoid(r[:, 3:6])
        n = F.softplus(r[:, 6])
        wi, wo = g.wi, g.wo
        cos_a = (wi[:, 2] * wo[:, 2] - (wi[:, 0] * wo[:, 0] + wi[:, 1] * wo[:, 1])).clamp_max(1.0)
        up = cos_a > 0
        # The lobe lives where cos α > 0 only; the inner where keeps pow's gradient finite elsewhere.
        lobe = torch.where(up, (n + 2.0) * (0.5 * INV_PI) * torch.where(up, cos_a, 1.0).pow(n), 0.0)
        return finish(g, kd * INV_PI + ks * lobe[:, None])

    def torrance_sparrow(raw, obj, wi, wo):  # torrance_sparrow.rs
        g, r = HalfGeometry(wi, wo), raw_at(raw)
        kd, ks = sigmoid(r[:, 0:3]), sigmoid(r[:, 3:6])
        alpha = clamp_alpha(sigmoid(0.5 * r[:, 6]))
        dg = beckmann_d(g, alpha) * v_cavity_g_over_4cos(g)
        return finish(g, kd * INV_PI + dg[:, None] * fresnel_schlick(ks, g.cos_d[:, None]))

    def fmbrdf(raw, obj, wi, wo):  # fresnel_microfacet.rs
        g, r = HalfGeometry(wi, wo), raw_at(raw)
        rho, ks = sigmoid(r[:, 0:3]), sigmoid(r[:, 3])
        alpha = clamp_alpha(sigmoid(0.5 * r[:, 4]))
        beta = 0.5 + 3.5 * sigmoid(r[:, 5])  # BETA_RANGE
        eta = 1.0 + 2.0 * sigmoid(r[:, 6])  # ETA_RANGE
        norm = torch.exp(raw_at(obj)[..., 0].clamp(-80.0, 80.0))
        theta_h = torch.atan2(g.sin2_h.sqrt(), g.cos_h)
        ndf = norm * torch.exp(-(theta_h / alpha).pow(beta))
        surface = ks * ndf * v_cavity_g_over_4cos(g) * fresnel_dielectric(g.cos_d, eta)
        body = INV_PI * ((1.0 - fresnel_dielectric(g.cos_i, eta)) * (1.0 - fresnel_dielectric(g.cos_o, eta)))
        return finish(g, surface[:, None] + rho * body[:, None])

    def disney(raw, obj, wi, wo):  # disney.rs
        g, r = HalfGeometry(wi, wo), raw_at(raw)
        p = sigmoid(r)
        c = p[:, 0:3]
        subsurface, metallic, specular, specular_tint = p[:, 3], p[:, 4], p[:, 5:6], p[:, 6:7]
        rough = sigmoid(0.5 * r[:, 7])
        sheen, sheen_tint, clearcoat, clearcoat_gloss = p[:, 8:9], p[:, 9:10], p[:, 10], p[:, 11]
        lum = 0.3 * c[:, 0] + 0.6 * c[:, 1] + 0.1 * c[:, 2]
        pos = lum > 0
        tint = torch.where(pos[:, None], c / torch.where(pos, lum, 1.0)[:, None], 1.0)

        fl, fv, fh = schlick_weight(g.cos_i), schlick_weight(g.cos_o), schlick_weight(g.cos_d)
        cd2 = g.cos_d * g.cos_d
        fd90 = 0.5 + 2.0 * cd2 * rough
        fd = lerp(1.0, fd90, fl) * lerp(1.0, fd90, fv)
        fss90 = cd2 * rough
        fss = lerp(1.0, fss90, fl) * lerp(1.0, fss90, fv)
        ss = 1.25 * (fss * (1.0 / (g.cos_i + g.cos_o) - 0.5) + 0.5)
        diffuse = lerp(fd, ss, subsurface) * INV_PI

        alpha = (rough * rough).clamp_min(ALPHA_MIN)
        ds = ggx_d(g, alpha)
        gs = smith_ggx_g1_over_2cos(g.cos_i, alpha) * smith_ggx_g1_over_2cos(g.cos_o, alpha)

        dr = gtr1_d(g, lerp(0.1, 0.001, clearcoat_gloss))
        fr = lerp(0.04, 1.0, fh)
        gr = smith_ggx_g1_over_2cos(g.cos_i, 0.25) * smith_ggx_g1_over_2cos(g.cos_o, 0.25)
        coat = 0.25 * clearcoat * gr * fr * dr

        m = metallic[:, None]
        spec0 = lerp(specular * 0.08 * lerp(1.0, tint, specular_tint), c, m)
        fs = lerp(spec0, 1.0, fh[:, None])
        sh = fh[:, None] * sheen * lerp(1.0, tint, sheen_tint)
        f = (diffuse[:, None] * c + sh) * (1.0 - m) + (gs * ds)[:, None] * fs + coat[:, None]
        return finish(g, f)

    return {
        "lambert": lambert,
        "phong": phong,
        "torrance-sparrow": torrance_sparrow,
        "fmbrdf": fmbrdf,
        "disney": disney,
    }


class CheckFailed(Exception):
    pass


def check_parametric(torch, arch):
    """Raises CheckFailed unless the transcription reproduces the core's values in the spec's check
    samples (evaluated in float64 at the exact float32 inputs the core saw); returns the largest
    relative difference."""
    name, kind, checks = arch["model"], arch["parametric"], arch.get("checks", [])
    model = brdf_models(torch).get(kind)
    if model is None:
        raise CheckFailed(f"{name}: no transcription of the parametric model {kind!r}")
    if not checks:
        raise CheckFailed(f"{name}: the spec has no check samples for {kind}")

    def column(key):
        return torch.tensor([c[key] for c in checks], dtype=torch.float32).double()

    want = column("f")
    got = model(column("raw"), column("object"), column("wi"), column("wo"))
    err = (got - want).abs()
    bad = (err > CHECK_RTOL * want.abs() + CHECK_ATOL).any(1).nonzero().flatten().tolist()
    if bad:
        i = bad[0]
        c = checks[i]
        raise CheckFailed(
            f"{name}: the PyTorch {kind} differs from the core's at check sample {i} of {len(checks)} "
            f"(raw {c['raw']}, object {c['object']}, wi {c['wi']}, wo {c['wo']}): "
            f"torch {got[i].tolist()}, core {want[i].tolist()}; {len(bad)} samples differ"
        )
    return (err / want.abs().clamp_min(CHECK_ATOL)).max().item()


def step_fn(torch, spec, arch):
    F = torch.nn.functional
    nets, inputs, valid, incident, target = build(torch, arch, spec["batch"])
    head = arch["head"]
    params = list(nets.parameters())
    if head == "parametric":
        check_parametric(torch, arch)
        brdf = brdf_models(torch)[arch["parametric"]]
        # Per-object raw parameters (FMBRDF's log NDF normalisation), trained with the networks.
        obj = torch.nn.Parameter(torch.tensor(arch.get("object", []), dtype=torch.float32))
        if obj.numel():
            params.append(obj)
    opt = torch.optim.Adam(params, lr=spec["lr"])

    def forward():
        outs = []
        for net in nets:
            parts = [outs[0] if p == "net0" else inputs[p] for p in net.input]
            outs.append(net(parts[0] if len(parts) == 1 else torch.cat(parts, 1)))
        out = outs[-1]
        f_d = f_s = None
        if head == "softplus":
            f = F.softplus(out)
        elif head == "parametric":
            f = brdf(out, obj, inputs["wi"], inputs["wo"])
        else:
            d, s = outs[-2], outs[-1]
            f_d = torch.sigmoid(d) / math.pi
            f_s = F.softplus(s[:, :3])
            f = (1.0 - torch.sigmoid(s[:, 3:6])) * f_d + f_s if head == "additive-enhanced" else f_d + f_s
        return f * valid, f_d, f_s

    def step():
        f, f_d, f_s = forward()
        loss = (gamma(torch, f * incident) - target).square().mean()
        if head == "additive-enhanced":
            rd = (gamma(torch, f_d * valid * incident) - target).abs().mean()
            rs = gamma(torch, f_s * incident).abs().mean()
            loss = loss + spec["lambda_diffuse"] * rd + spec["lambda_specular"] * rs
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    return step


STEPS = {}


def time_arch(torch, spec, arch):
    """ms per step over `steps` steps; the model is built (and warmed up) on its first request only,
    so the trainer's rounds time the same optimiser run, as its own rounds do."""
    step = STEPS.get(arch["model"])
    if step is None:
        step = STEPS[arch["model"]] = step_fn(torch, spec, arch)
        step()  # warm-up: allocator, oneDNN primitive caches
    t = time.perf_counter()
    for _ in range(max(spec["steps"], 1)):
        step()
    return (time.perf_counter() - t) * 1e3 / max(spec["steps"], 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("spec", help="JSON written by trainer bench-step --torch")
    ap.add_argument("--serve", action="store_true", help="read architecture names from stdin, answer one JSON line each")
    ap.add_argument("--steps", type=int, help="override the spec's timed steps")
    ap.add_argument("--check", action="store_true", help="only check the parametric formulas against the spec's samples")
    args = ap.parse_args()
    try:
        import torch
    except Exception as e:  # ImportError, or a CUDA wheel whose libraries are missing
        reply({"error": f"cannot import torch: {e}"})
        return 2
    with open(args.spec) as f:
        spec = json.load(f)
    if args.steps:
        spec["steps"] = args.steps
    torch.set_num_threads(spec["threads"])
    archs = {a["model"]: a for a in spec["archs"]}
    if args.check:
        checked, errors = {}, []
        for a in spec["archs"]:
            if a["head"] == "parametric":
                try:
                    checked[a["model"]] = check_parametric(torch, a)
                except CheckFailed as e:
                    errors.append(str(e))
        # The largest relative difference per model, so that a shrinking margin shows before it fails.
        reply({"checked": checked, "errors": errors} if errors else {"checked": checked})
        return 1 if errors else 0

    def timed(a):
        try:
            return {"model": a["model"], "ms_per_step": time_arch(torch, spec, a)}
        except CheckFailed as e:
            return {"model": a["model"], "error": str(e)}

    if args.serve:
        reply({"torch": torch.__version__, "threads": torch.get_num_threads()})
        for line in sys.stdin:
            name = line.strip()
            if not name:
                break
            if name not in archs:
                reply({"error": f"unknown architecture {name}"})
                continue
            reply(timed(archs[name]))
        return 0
    out = [timed(a) for a in spec["archs"]]
    reply({"torch": torch.__version__, "threads": torch.get_num_threads(), "batch": spec["batch"], "results": out})
    return 0


if __name__ == "__main__":
    sys.exit(main())
