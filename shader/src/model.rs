//! A `.nbrdf` model as WGSL: its networks, the position and angle encodings, the output maps and the
//! sampling, wired as `docs/models.md` describes the forward pass.

use std::fmt::Write;

use nbrdf::energy::AlbedoBound;
use nbrdf::file::{ModelKind, PositionEncoding, Reciprocity};
use nbrdf::parametric::ParametricKind;
use nbrdf::sampling::{Proxy, ViewProxy};
use nbrdf::{Model, Weights};

use crate::network::{self, lit, Network, Storage};
use crate::Body;

/// The WGSL names of a parametric model: its struct and function prefix.
fn parametric_names(kind: ParametricKind) -> (&'static str, &'static str) {
    match kind {
        ParametricKind::Lambert => ("NbrdfLambert", "nbrdf_lambert"),
        ParametricKind::Phong => ("NbrdfPhong", "nbrdf_phong"),
        ParametricKind::TorranceSparrow => ("NbrdfTorranceSparrow", "nbrdf_torrance_sparrow"),
        ParametricKind::FresnelMicrofacet => ("NbrdfFresnelMicrofacet", "nbrdf_fresnel_microfacet"),
        ParametricKind::Disney => ("NbrdfDisney", "nbrdf_disney"),
    }
}

/// A human name of the model for the file's header comment.
pub(crate) fn describe(model: &Model<'_>) -> String {
    let h = model.header();
    let kind = match h.kind {
        ModelKind::Parametric(k) => format!("Parametric({})", k.name()),
        ModelKind::SingleMlp if h.n_nets == 2 => format!("SingleMlp (trunk + {}-layer head)", h.nets()[1].hidden),
        k => format!("{k:?}{}", if h.enhanced { ", enhanced (Eq. 8)" } else { "" }),
    };
    let position = match h.position {
        PositionEncoding::Uniform => "uniform".to_string(),
        PositionEncoding::Intrinsic { k } => format!("intrinsic (k = {k})"),
        PositionEncoding::Extrinsic { frequencies } => format!("extrinsic (PE of xyz, {frequencies} octaves)"),
    };
    let nets: Vec<String> =
        h.nets().iter().map(|n| format!("Mlp({}, {}, {}, {}, {})", n.n_in, n.width, n.hidden, n.n_out, n.skip)).collect();
    format!(
        "{kind}; reciprocity {:?}; {} angle octaves; position {position}; networks {}",
        h.reciprocity,
        h.angle_frequencies,
        nets.join(", ")
    )
}

/// `array<f32, n>(a[0], ..., a[n-1])`-style constructor of the given element expressions.
fn array_of(items: &[String]) -> String {
    format!("array<f32, {}>({})", items.len(), items.join(", "))
}

/// `name[0], ..., name[n-1]`.
fn elements(name: &str, n: usize) -> Vec<String> {
    (0..n).map(|i| format!("{name}[{i}]")).collect()
}

/// Writes `fn name(v: array<f32, n>) -> array<f32, n (1 + 2F)>`: the positional encoding of
/// `docs/models.md`, `[v, sin 2^0 v, cos 2^0 v, ...]` per value.
pub(crate) fn emit_encoding(out: &mut String, name: &str, n: usize, frequencies: usize) {
    let block = 1 + 2 * frequencies;
    let _ = writeln!(out, "fn {name}(v: array<f32, {n}>) -> array<f32, {}> {{", n * block);
    let mut items = Vec::new();
    for j in 0..n {
        items.push(format!("v[{j}]"));
        for k in 0..frequencies {
            // 2^k · v is exact, as the core's argument is.
            let _ = writeln!(out, "    let sc{j}_{k} = nbrdf_sincos(v[{j}] * {});", lit((1u64 << k) as f32));
            items.push(format!("sc{j}_{k}.x"));
            items.push(format!("sc{j}_{k}.y"));
        }
    }
    let _ = writeln!(out, "    return {};\n}}\n", array_of(&items));
}

/// The shader body of a validated model, its storage decided.
pub(crate) fn body(model: &Model<'_>, storage: Storage) -> Body {
    let h = *model.header();
    let Weights::F32(w) = model.weights() else {
        unreachable!("ModelBuf holds f16 files widened to f32");
    };
    let mut nets = Vec::new();
    let mut off = 0;
    for d in h.nets() {
        nets.push(Network::from_desc(d, &w[off..off + d.n_weights()]));
        off += d.n_weights();
    }
    let k = model.position_len();
    let p = h.position.encoded_len();
    let mut code = String::new();
    let mut buffer = Vec::new();
    for (i, net) in nets.iter().enumerate() {
        let start = match storage {
            Storage::Buffer { .. } => net.append_weights(&mut buffer),
            Storage::Inline => 0,
        };
        network::emit(&mut code, &format!("nbrdf_net{i}"), net, storage, start);
    }
    // The position input as the networks see it.
    let (param, arg) = if k > 0 { (format!(", p: array<f32, {k}>"), ", p") } else { (String::new(), "") };
    if let PositionEncoding::Extrinsic { frequencies } = h.position {
        emit_encoding(&mut code, "nbrdf_encode_position", 3, frequencies as usize);
    }
    let pos_items = match h.position {
        PositionEncoding::Uniform => vec![],
        PositionEncoding::Intrinsic { .. } => elements("p", k),
        PositionEncoding::Extrinsic { .. } => elements("pe", p),
    };
    let pos_let = match h.position {
        PositionEncoding::Extrinsic { .. } => "    let pe = nbrdf_encode_position(p);\n",
        _ => "",
    };
    let call = |i: usize, inputs: &[String]| {
        if inputs.is_empty() {
            format!("nbrdf_net{i}()")
        } else {
            format!("nbrdf_net{i}({})", array_of(inputs))
        }
    };
    let macs: usize = nets.iter().map(Network::macs).sum();
    // A bounded model's networks and formula evaluate `f`; `nbrdf_eval` divides it (`emit_bound`).
    let eval_fn = if h.albedo_bound.is_some() { "nbrdf_eval_unbounded" } else { "nbrdf_eval" };
    let sample_bound = |call: String| match h.albedo_bound {
        Some(_) => format!("nbrdf_bound_sample({call}, wo)"),
        None => call,
    };

    match h.kind {
        ModelKind::Parametric(kind) => {
            let (ty, prefix) = parametric_names(kind);
            let n_raw = kind.n_raw();
            let raw = array_of(&elements("r", n_raw));
            let object = if kind.n_object() > 0 { format!(", {}", lit(model.object_parameters()[0])) } else { String::new() };
            let _ = write!(
                code,
                "// The parameters the network predicts at the point (core `Model::prepare`).\n\
                 fn nbrdf_params({}) -> {ty} {{\n{pos_let}    let r = {};\n    return {prefix}_from_raw({raw}{object});\n}}\n\n",
                param.trim_start_matches(", "),
                call(0, &pos_items),
            );
            let _ = write!(
                code,
                "fn {eval_fn}(wi: vec3<f32>, wo: vec3<f32>{param}) -> vec3<f32> {{\n\
                 \x20   let pair = nbrdf_upper_pair(wi, wo);\n\
                 \x20   if (!pair.ok) {{\n        return vec3<f32>(0.0);\n    }}\n\
                 \x20   return {prefix}_eval(nbrdf_params({a}), pair.wi, pair.wo);\n}}\n\n\
                 fn nbrdf_pdf(wi: vec3<f32>, wo: vec3<f32>{param}) -> f32 {{\n\
                 \x20   return {prefix}_pdf(nbrdf_params({a}), wo, wi);\n}}\n\n\
                 fn nbrdf_sample(wo: vec3<f32>, u: vec3<f32>{param}) -> NbrdfSample {{\n\
                 \x20   return {};\n}}\n\n",
                sample_bound(format!("{prefix}_sample(nbrdf_params({a}), u, wo)", a = arg.trim_start_matches(", "))),
                a = arg.trim_start_matches(", "),
            );
        }
        kind => {
            let n_angles = h.reciprocity.n_angles();
            let freqs = h.angle_frequencies as usize;
            emit_encoding(&mut code, "nbrdf_encode_angles", n_angles, freqs);
            let angles = match h.reciprocity {
                Reciprocity::Exact => "let a = nbrdf_theta(frame);\n    let e = nbrdf_encode_angles(array<f32, 4>(a.x, a.y, a.z, a.w));",
                Reciprocity::None | Reciprocity::Swap => {
                    "let a = nbrdf_rusinkiewicz(frame);\n    let e = nbrdf_encode_angles(array<f32, 3>(a.x, a.y, a.z));"
                }
            };
            let e_items = elements("e", h.angle_input_len());
            let joined = |first: Vec<String>| -> Vec<String> { first.into_iter().chain(e_items.iter().cloned()).collect() };
            let width0 = h.nets()[0].output_len();
            let rgb = match kind {
                ModelKind::SingleMlp if h.n_nets == 2 => format!(
                    "    let t = {};\n    let y = {};\n    return nbrdf_sanitize(vec3<f32>(nbrdf_softplus(y[0]), nbrdf_softplus(y[1]), nbrdf_softplus(y[2])));\n",
                    call(0, &pos_items),
                    call(1, &joined(elements("t", width0)))
                ),
                ModelKind::SingleMlp => format!(
                    "    let y = {};\n    return nbrdf_sanitize(vec3<f32>(nbrdf_softplus(y[0]), nbrdf_softplus(y[1]), nbrdf_softplus(y[2])));\n",
                    call(0, &joined(pos_items.clone()))
                ),
                ModelKind::AdditiveSeparate => format!(
                    "    let d = {};\n    let s = {};\n{}",
                    call(0, &pos_items),
                    call(1, &joined(pos_items.clone())),
                    combine(h.enhanced)
                ),
                ModelKind::AdditiveShared => format!(
                    "    let t = {};\n    let d = {};\n    let s = {};\n{}",
                    call(0, &pos_items),
                    call(1, &elements("t", width0)),
                    call(2, &joined(elements("t", width0))),
                    combine(h.enhanced)
                ),
                ModelKind::Parametric(_) => unreachable!(),
            };
            let _ = write!(
                code,
                "fn {eval_fn}(wi: vec3<f32>, wo: vec3<f32>{param}) -> vec3<f32> {{\n\
                 \x20   let pair = nbrdf_upper_pair(wi, wo);\n\
                 \x20   if (!pair.ok) {{\n        return vec3<f32>(0.0);\n    }}\n\
                 \x20   let frame = nbrdf_half_frame(pair.wi, pair.wo);\n\
                 \x20   if (!frame.ok) {{\n        return vec3<f32>(0.0);\n    }}\n\
                 \x20   {angles}\n{pos_let}{rgb}}}\n\n"
            );
            emit_proxy_sampling(&mut code, &model.proxy(), model.header().view_proxy.as_ref(), &param, arg);
        }
    }
    if let Some(bound) = &h.albedo_bound {
        emit_bound(&mut code, bound, &param, arg);
    }
    Body { code, buffer, position_len: k, macs, parametric: matches!(h.kind, ModelKind::Parametric(_)), json: false }
}

/// `nbrdf_eval` of an energy-bounded model (core `AlbedoBound::apply`): `f` of `nbrdf_eval_unbounded`
/// divided per channel by `max(1, Â(θi), Â(θo))`, with `Â` the table of the file; and the sample
/// weight of a parametric model's own lobes divided the same way.
fn emit_bound(code: &mut String, bound: &AlbedoBound, param: &str, arg: &str) {
    let n = bound.cells.len();
    let cells: Vec<String> = bound.cells.iter().map(|c| format!("vec3<f32>({}, {}, {})", lit(c[0]), lit(c[1]), lit(c[2]))).collect();
    let _ = write!(
        code,
        "// The energy bound: per cell of cos θ, an upper bound of the albedo per channel (core `AlbedoBound`).\n\
         var<private> NBRDF_ALBEDO: array<vec3<f32>, {n}> = array<vec3<f32>, {n}>({});\n\n\
         fn nbrdf_albedo_cell(cos_t: f32) -> u32 {{\n\
         \x20   return min(u32((1.0 - cos_t) * {}), {}u);\n}}\n\n\
         fn nbrdf_bound(f: vec3<f32>, wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {{\n\
         \x20   let pair = nbrdf_upper_pair(wi, wo);\n\
         \x20   if (!pair.ok) {{\n        return f;\n    }}\n\
         \x20   let d = max(NBRDF_ALBEDO[nbrdf_albedo_cell(pair.wi.z)], NBRDF_ALBEDO[nbrdf_albedo_cell(pair.wo.z)]);\n\
         \x20   return select(f, f / d, d > vec3<f32>(1.0));\n}}\n\n\
         fn nbrdf_bound_sample(s: NbrdfSample, wo: vec3<f32>) -> NbrdfSample {{\n\
         \x20   var b = s;\n\
         \x20   if (s.ok) {{\n        b.weight = nbrdf_bound(s.weight, s.wi, wo);\n    }}\n\
         \x20   return b;\n}}\n\n\
         fn nbrdf_eval(wi: vec3<f32>, wo: vec3<f32>{param}) -> vec3<f32> {{\n\
         \x20   return nbrdf_bound(nbrdf_eval_unbounded(wi, wo{arg}), wi, wo);\n}}\n\n",
        cells.join(", "),
        lit(n as f32),
        n - 1,
    );
}

/// The additive split's output maps (core `neural::split`): `f_d = σ(d) / π` sanitised, `f_s =
/// softplus(s[0..3])`, enhanced `f = (1 - σ(s[3..6])) f_d + f_s`.
fn combine(enhanced: bool) -> String {
    let mut s = String::from(
        "    let fd = nbrdf_sanitize(vec3<f32>(nbrdf_sigmoid(d[0]), nbrdf_sigmoid(d[1]), nbrdf_sigmoid(d[2])) * NBRDF_INV_PI);\n\
         \x20   let fs = vec3<f32>(nbrdf_softplus(s[0]), nbrdf_softplus(s[1]), nbrdf_softplus(s[2]));\n",
    );
    if enhanced {
        s.push_str(
            "    let xi = vec3<f32>(nbrdf_sigmoid(s[3]), nbrdf_sigmoid(s[4]), nbrdf_sigmoid(s[5]));\n\
             \x20   return nbrdf_sanitize((vec3<f32>(1.0) - xi) * fd + fs);\n",
        );
    } else {
        s.push_str("    return nbrdf_sanitize(fd + fs);\n");
    }
    s
}

/// `nbrdf_pdf` and `nbrdf_sample` through the sampling proxy stored in the file (cosine without one),
/// or through its per-view table where it has one, evaluating the model for the weight (core
/// `Model::sample`, `ViewProxy::sample`).
pub(crate) fn emit_proxy_sampling(code: &mut String, proxy: &Proxy, view: Option<&ViewProxy>, param: &str, arg: &str) {
    // The mixture's probabilities and roughnesses: constants, or the row of wo's cell (the table
    // version first finds the cell, from the normalised view).
    let (mix, pdf_cell, sample_cell) = match view {
        None => {
            let [l0, l1] = proxy.lobes;
            let _ = write!(
                code,
                "// The sampling proxy: cosine, and GGX visible-normal lobes of roughness NBRDF_PROXY_ALPHA.\n\
                 const NBRDF_PROXY_P: vec3<f32> = vec3<f32>({}, {}, {});\n\
                 const NBRDF_PROXY_ALPHA: vec2<f32> = vec2<f32>({}, {});\n\n",
                lit(proxy.diffuse),
                lit(l0.weight),
                lit(l1.weight),
                lit(l0.alpha),
                lit(l1.alpha),
            );
            ("NBRDF_PROXY_P, NBRDF_PROXY_ALPHA", "", "")
        }
        Some(view) => {
            let n = view.nodes.len();
            let p: Vec<String> = view
                .nodes
                .iter()
                .map(|q| format!("vec3<f32>({}, {}, {})", lit(q.diffuse), lit(q.lobes[0].weight), lit(q.lobes[1].weight)))
                .collect();
            let a: Vec<String> =
                view.nodes.iter().map(|q| format!("vec2<f32>({}, {})", lit(q.lobes[0].alpha), lit(q.lobes[1].alpha))).collect();
            let _ = write!(
                code,
                "// The sampling table: per cell of cos θo, the selection probabilities of the cosine lobe and two\n\
                 // GGX visible-normal lobes, and those lobes' roughnesses (core `ViewProxy`).\n\
                 var<private> NBRDF_VIEW_P: array<vec3<f32>, {n}> = array<vec3<f32>, {n}>({});\n\
                 var<private> NBRDF_VIEW_ALPHA: array<vec2<f32>, {n}> = array<vec2<f32>, {n}>({});\n\n\
                 fn nbrdf_view_cell(cos_o: f32) -> u32 {{\n\
                 \x20   return min(u32((1.0 - cos_o) * {}), {}u);\n}}\n\n",
                p.join(", "),
                a.join(", "),
                lit(n as f32),
                n - 1,
            );
            (
                "NBRDF_VIEW_P[c], NBRDF_VIEW_ALPHA[c]",
                "    let wo = nbrdf_valid_wo(wo_in);\n    if (wo.w <= 0.0) {\n        return 0.0;\n    }\n    let c = nbrdf_view_cell(wo.z);\n",
                "    let c = nbrdf_view_cell(wo.z);\n",
            )
        }
    };
    let _ = write!(
        code,
        "fn nbrdf_pdf(wi: vec3<f32>, wo_in: vec3<f32>{param}) -> f32 {{\n\
         {pdf_cell}\
         \x20   return nbrdf_proxy_pdf({mix}, wo_in, wi);\n}}\n\n\
         fn nbrdf_sample(wo_in: vec3<f32>, u: vec3<f32>{param}) -> NbrdfSample {{\n\
         \x20   let wo = nbrdf_valid_wo(wo_in);\n\
         \x20   if (wo.w <= 0.0) {{\n        return nbrdf_no_sample();\n    }}\n\
         {sample_cell}\
         \x20   let wi = nbrdf_proxy_sample_wi({mix}, u, wo.xyz);\n\
         \x20   if (wi.w <= 0.0) {{\n        return nbrdf_no_sample();\n    }}\n\
         \x20   let pdf = nbrdf_proxy_pdf({mix}, wo.xyz, wi.xyz);\n\
         \x20   return nbrdf_finish(wi.xyz, pdf, nbrdf_eval(wi.xyz, wo.xyz{arg}));\n}}\n\n",
    );
}
