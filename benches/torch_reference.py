#!/usr/bin/env python3
"""PyTorch twin of `trainer bench-step`: one training step (forward, backward, Adam) of each nbrdf
architecture, for the issue 8 comparison "ours at most 0.7x PyTorch's time".

The architectures are not transcribed here: `trainer bench-step --torch` writes them (layer sizes in
file order, ReLU count, skip layer, what each network reads, the output head) to a JSON spec that this
script reads, so both sides build identical networks. Run through the trainer it serves one
architecture per request (`--serve`, interleaved with our own timing); run alone it times every
architecture of a spec and prints JSON:

    trainer bench-step --torch                       # side by side, prints the ratio
    python3 benches/torch_reference.py spec.json     # PyTorch alone

What one step is, as in trainer/src/train.rs `objective` and models/mod.rs `Model::forward`:
  * networks: nn.Linear layers with ReLU after the first `hidden`, `cat([h, x])` into layer `skip`;
  * head: softplus of the single MLP's output; additive: f = sigmoid(d)/pi + softplus(s[:, :3]),
    enhanced (Eq. 8): f = (1 - sigmoid(s[:, 3:6])) * f_d + f_s plus the Sec. 4.4 L1 regularisers;
    parametric: the same parameter network, then softplus of its first 3 raw outputs in place of the
    BRDF formula (ours evaluates the core's formula in a custom op with central-difference gradients;
    a PyTorch twin of Disney & co. would cost more, so PyTorch's time here is a lower bound);
  * loss (Eq. 9/10): mean over 3N of (srgb(clamp(f * valid * incident, 0, 1)) - target)^2;
  * optimiser: torch.optim.Adam with PyTorch's defaults and the trainer's lr.
Inputs are random with the encoded widths; timing does not depend on their values beyond the ReLU
pattern. Requires `pip install torch` (any 2.x, the CPU build suffices).
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
    valid = torch.ones(batch, 1)
    incident = torch.rand(batch, 3)
    target = torch.rand(batch, 3)
    return nets, inputs, valid, incident, target


def gamma(torch, x):
    c = x.clamp(0.0, 1.0)
    curve = 1.055 * c.clamp_min(SRGB_KNEE).pow(1.0 / 2.4) - 0.055
    return torch.where(c > SRGB_KNEE, curve, 12.92 * c)


def step_fn(torch, spec, arch):
    F = torch.nn.functional
    nets, inputs, valid, incident, target = build(torch, arch, spec["batch"])
    opt = torch.optim.Adam(nets.parameters(), lr=spec["lr"])
    head = arch["head"]

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
            f = F.softplus(out[:, :3])
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
    if args.serve:
        reply({"torch": torch.__version__, "threads": torch.get_num_threads()})
        for line in sys.stdin:
            name = line.strip()
            if not name:
                break
            if name not in archs:
                reply({"error": f"unknown architecture {name}"})
                continue
            reply({"model": name, "ms_per_step": time_arch(torch, spec, archs[name])})
        return 0
    out = [{"model": a["model"], "ms_per_step": time_arch(torch, spec, a)} for a in spec["archs"]]
    reply({"torch": torch.__version__, "threads": torch.get_num_threads(), "batch": spec["batch"], "results": out})
    return 0


if __name__ == "__main__":
    sys.exit(main())
