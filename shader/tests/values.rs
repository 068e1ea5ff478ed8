//! The exported shader computes the core's values: every model kind runs its compute entry point on a
//! Vulkan adapter (Mesa lavapipe where there is no GPU: `.ci/shader.sh`) over ≥ 4096 direction pairs
//! with the hard cases (grazing, wi = wo, mirror pairs, the pole, below the horizon, unnormalised),
//! and eval, pdf and sample agree with `nbrdf::Model` within 1e-5 relative; Θ models are reciprocal bit
//! for bit in the shader. Needs `--features gpu`; prints SKIPPED without it or without an adapter.

mod common;

#[cfg(not(feature = "gpu"))]
#[test]
fn values_agree_with_the_core_on_an_adapter() {
    eprintln!("SKIPPED: the shader's values are compared on a Vulkan adapter with --features gpu (.ci/shader.sh)");
}

#[cfg(feature = "gpu")]
mod on_gpu {
    use super::common::{self, Rng};
    use nbrdf::file::Reciprocity;
    use nbrdf::measured::nbrdf_json::NbrdfNetwork;
    use nbrdf::{Brdf, ModelBuf, Vec3};
    use nbrdf_shader::gpu::Gpu;
    use nbrdf_shader::{export, Options, Storage, DEFAULT_BUFFER, TEST_OUT_STRIDE};

    /// Relative agreement asked of f32 results: `|shader - core| ≤ TOL · max(|core|, floor)`, the floor
    /// 1e-2 of the largest value of the model's channel: below it a value is a cancellation of larger
    /// terms (a network output near 0), whose relative rounding is unbounded in any two f32 sums.
    const TOL: f64 = 1e-5;
    const FLOOR: f64 = 1e-2;

    /// Whether the core's φd lies within 1e-3 of the seam of its half plane (0, π, 2π): there a pair's
    /// φd (and Θ's φd mod π) jumps by π under a rounding of its inputs, so two correct f32 maps may
    /// land on either side (the BRDF a trained network learns is continuous there; random weights are
    /// not).
    fn on_seam(wi: Vec3, wo: Vec3) -> bool {
        if nbrdf::angles::upper_hemisphere_pair(wi, wo).is_none() {
            return false;
        }
        match nbrdf::angles::to_rusinkiewicz(wi, wo) {
            Some(r) => {
                let m = r.phi_d % std::f32::consts::PI;
                !(1e-3..=std::f32::consts::PI - 1e-3).contains(&m)
            }
            None => false,
        }
    }

    /// Direction pairs: random ones over the hemisphere, then the hard cases; each followed by its swap.
    fn pairs(rng: &mut Rng, n_random: usize) -> Vec<(Vec3, Vec3)> {
        let dir = |rng: &mut Rng| {
            let (z, phi) = (rng.next().max(1e-4), rng.next() * std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        let mut base = Vec::new();
        for _ in 0..n_random {
            base.push((dir(rng), dir(rng)));
        }
        let w = Vec3::new(0.48, -0.36, 0.8);
        for z in [1e-6f32, 1e-3, 0.02, 0.1] {
            let g = Vec3::new((1.0 - z * z).sqrt(), 0.0, z); // grazing
            base.push((g, w));
            base.push((w, g));
            base.push((g, Vec3::new(-g.x, 0.0, g.z))); // grazing mirror pair
        }
        for _ in 0..64 {
            let d = dir(rng);
            base.push((d, d)); // wi = wo
            base.push((d, Vec3::new(-d.x, -d.y, d.z))); // mirror: the half vector is the normal
            base.push((Vec3::new(d.x * 1e-4, d.y * 1e-4, 1.0), d)); // near the pole
            base.push((d * 1e-20, d * 3.0)); // unnormalised
            base.push((d * 1e20, Vec3::new(d.y, d.x, d.z)));
            base.push((Vec3::new(d.x, d.y, -d.z), d)); // below the horizon
            base.push((d, Vec3::new(d.x, d.y, 0.0))); // on the horizon
        }
        base.push((Vec3::Z, Vec3::Z));
        base.push((Vec3::Z, Vec3::new(0.0, 0.0, -1.0))); // wi = -wo
        base.push((Vec3::ZERO, Vec3::Z));
        base.push((Vec3::new(f32::NAN, 0.0, 1.0), Vec3::Z));
        base.push((Vec3::new(0.0, f32::INFINITY, 1.0), Vec3::Z));
        base.into_iter().flat_map(|(a, b)| [(a, b), (b, a)]).collect()
    }

    /// The worst relative errors of a model: eval, pdf, the sample's weight and pdf; and how many
    /// samples took another lobe or direction (a uniform on a lobe boundary, rounding apart).
    #[derive(Default, Debug)]
    struct Errors {
        eval: f64,
        pdf: f64,
        sample: f64,
        sample_pdf: f64,
        weight_excess: f64,
        conditioning: f64,
        sample_mismatch: usize,
        samples: usize,
        pairs: usize,
        reciprocity_failures: usize,
        seam: usize,
        direction: f64,
        worst: String,
        worst_sample: String,
        eval_excess: f64,
        eval_conditioning: f64,
    }

    /// Ulps of a unit vector by which two correct f32 evaluations of the same directions may differ
    /// inside: normalising each direction, their sum and its normalisation (the half vector) are about
    /// four roundings, in either's own order (and fused or not).
    const ULPS: f32 = 4.0;

    /// The largest change of `f` (per channel) when `wi` or `wo` moves by `ULPS` ulps of its length
    /// along any axis: where `f` is ill-conditioned in the directions (a narrow lobe's peak at grazing
    /// angles, a network output near 0) that much of a difference is rounding, not a wrong formula.
    fn spread(f: &dyn Fn(Vec3, Vec3) -> [f64; 3], wi: Vec3, wo: Vec3) -> [f64; 3] {
        let at = f(wi, wo);
        let mut s = [0.0f64; 3];
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            for sign in [-1.0f32, 1.0] {
                let d = axis * (sign * ULPS * f32::EPSILON);
                for moved in [f(wi + d * wi.length(), wo), f(wi, wo + d * wo.length())] {
                    for c in 0..3 {
                        if moved[c].is_finite() {
                            s[c] = s[c].max((moved[c] - at[c]).abs());
                        }
                    }
                }
            }
        }
        s
    }

    fn rel(got: f32, want: f32, floor: f64) -> f64 {
        if got.to_bits() == want.to_bits() {
            return 0.0;
        }
        (got as f64 - want as f64).abs() / (want.abs() as f64).max(floor).max(1e-30)
    }

    /// Runs `queries` (wi, wo, u, p per query) on the adapter and compares with `core(query) ->
    /// (eval, pdf, sample)`.
    #[allow(clippy::type_complexity)]
    fn compare(
        gpu: &Gpu,
        shader: &nbrdf_shader::Shader,
        queries: &[(Vec3, Vec3, [f32; 3], Vec<f32>)],
        core: &dyn Fn(&(Vec3, Vec3, [f32; 3], Vec<f32>)) -> ([f32; 3], f32, Option<nbrdf::sampling::BsdfSample>),
        exact_reciprocity: bool,
        seams: bool,
    ) -> Errors {
        let mut flat = Vec::new();
        for (wi, wo, u, p) in queries {
            flat.extend_from_slice(&[wi.x, wi.y, wi.z, wo.x, wo.y, wo.z, u[0], u[1], u[2]]);
            flat.extend_from_slice(p);
        }
        let out = gpu.run(shader, &flat).unwrap_or_else(|e| panic!("{}: {e}", shader.description));
        let want: Vec<_> = queries.iter().map(core).collect();
        // Per channel, the largest value: the floor of the relative errors.
        let mut scale = [0.0f64; 3];
        let mut pdf_scale = 0.0f64;
        for (f, pdf, _) in &want {
            (0..3).for_each(|c| scale[c] = scale[c].max(f[c] as f64));
            pdf_scale = pdf_scale.max(*pdf as f64);
        }
        let mut e = Errors { pairs: queries.len(), ..Errors::default() };
        for (i, (q, (f, pdf, s))) in queries.iter().zip(&want).enumerate() {
            let o = &out[i * TEST_OUT_STRIDE..(i + 1) * TEST_OUT_STRIDE];
            let seam = seams && on_seam(q.0, q.1);
            e.seam += seam as usize;
            let eval_at = |wi: Vec3, wo: Vec3| core(&(wi, wo, q.2, q.3.clone())).0.map(f64::from);
            let mut eval_spread = None;
            for c in 0..3 {
                assert!(o[c].is_finite() && o[c] >= 0.0, "{}: query {i} gave {:?}", shader.description, &o[..3]);
                if seam {
                    continue;
                }
                let r = rel(o[c], f[c], FLOOR * scale[c]);
                if r > e.eval && e.eval_excess == 0.0 {
                    e.worst = format!("{:?} -> shader {:?} core {:?}", (q.0, q.1), &o[..3], f);
                }
                e.eval = e.eval.max(r);
                if r > TOL {
                    let s = *eval_spread.get_or_insert_with(|| spread(&eval_at, q.0, q.1));
                    let allowed = s[c] / (f[c].abs() as f64).max(FLOOR * scale[c]).max(1e-30);
                    e.eval_conditioning = e.eval_conditioning.max(allowed);
                    if r - allowed > e.eval_excess {
                        e.eval_excess = r - allowed;
                        e.worst = format!("{:?} -> shader {:?} core {:?} (spread {:?})", (q.0, q.1), &o[..3], f, s);
                    }
                }
            }
            e.pdf = e.pdf.max(rel(o[3], *pdf, FLOOR * pdf_scale));
            let ok = o[11] != 0.0;
            match s {
                Some(_) if ok && seam => {}
                Some(s) if ok => {
                    e.samples += 1;
                    let wi = Vec3::new(o[4], o[5], o[6]);
                    let d = (wi - s.wi).length() as f64;
                    if d > 1e-3 {
                        e.sample_mismatch += 1;
                        continue;
                    }
                    e.direction = e.direction.max(d);
                    // Specular samples crowd the plane of wo and the normal, the seam.
                    if seams && on_seam(wi, q.1) {
                        e.seam += 1;
                        continue;
                    }
                    // The warps are ill-conditioned near the rim (z = sqrt(1 - r²)): the sample's pdf
                    // and weight are checked at the shader's own direction.
                    let weight_at = |w: Vec3| {
                        let (f, pdf, _) = core(&(w, q.1, q.2, q.3.clone()));
                        (f.map(|v| v as f64 * w.z as f64 / pdf as f64), pdf)
                    };
                    let (weight, pdf) = weight_at(wi);
                    let r_pdf = rel(o[7], pdf, FLOOR * pdf_scale);
                    e.sample = e.sample.max(r_pdf);
                    if r_pdf > TOL {
                        // A narrow proxy lobe's pdf at its own peak is ill-conditioned as the weight is.
                        let pdf_of = |wi: Vec3, wo: Vec3| [core(&(wi, wo, q.2, q.3.clone())).1 as f64; 3];
                        let allowed = spread(&pdf_of, wi, q.1)[0] / (pdf as f64).max(FLOOR * pdf_scale).max(1e-30);
                        e.sample_pdf = e.sample_pdf.max(r_pdf - allowed);
                    }
                    // Beyond TOL, the weight's own change under a few ulps of the directions (`spread`).
                    let weight_of = |wi: Vec3, wo: Vec3| {
                        let (f, pdf, _) = core(&(wi, wo, q.2, q.3.clone()));
                        f.map(|v| v as f64 * wi.z as f64 / pdf as f64)
                    };
                    let spread = spread(&weight_of, wi, q.1);
                    let w_scale = weight.iter().fold(0.0f64, |a, b| a.max(*b));
                    for c in 0..3 {
                        let denom = weight[c].abs().max(FLOOR * w_scale).max(1e-30);
                        let r = if o[8 + c].to_bits() == (weight[c] as f32).to_bits() { 0.0 } else { (o[8 + c] as f64 - weight[c]).abs() / denom };
                        e.sample = e.sample.max(r);
                        e.conditioning = e.conditioning.max(spread[c] / denom);
                        if r - spread[c] / denom > e.weight_excess {
                            e.weight_excess = r - spread[c] / denom;
                            e.worst_sample = format!("wo {:?} u {:?} -> wi {:?} weight shader {:?} core {:?} (spread {:?})", q.1, q.2, wi, &o[8..11], weight, spread);
                        }
                    }
                }
                None if !ok => {}
                _ => e.sample_mismatch += 1,
            }
        }
        // Queries come in swapped pairs (2i: (wi, wo), 2i + 1: (wo, wi)) with the same point.
        for i in (0..queries.len()).step_by(2) {
            let a = &out[i * TEST_OUT_STRIDE..i * TEST_OUT_STRIDE + 3];
            let b = &out[(i + 1) * TEST_OUT_STRIDE..(i + 1) * TEST_OUT_STRIDE + 3];
            if a.iter().zip(b).any(|(x, y)| x.to_bits() != y.to_bits()) {
                e.reciprocity_failures += 1;
            }
        }
        if exact_reciprocity {
            assert_eq!(e.reciprocity_failures, 0, "{}: Θ models are reciprocal bit for bit", shader.description);
        }
        e
    }

    fn check(name: &str, e: &Errors) {
        println!(
            "{name}: {} pairs, max relative error eval {:.2e} (beyond its conditioning {:.2e}; that conditioning up to {:.2e}), pdf {:.2e}, sample pdf beyond its conditioning {:.2e}, sample pdf or weight {:.2e} (beyond its conditioning {:.2e}; that conditioning up to {:.2e}; direction {:.1e}); {} of {} samples elsewhere; {} pairs not bitwise reciprocal; {} pairs or samples on the φd seam (not compared); worst eval {}; worst weight {}",
            e.pairs, e.eval, e.eval_excess, e.eval_conditioning, e.pdf, e.sample_pdf, e.sample, e.weight_excess, e.conditioning, e.direction, e.sample_mismatch, e.samples, e.reciprocity_failures, e.seam, e.worst, e.worst_sample
        );
        assert!(e.pairs >= 4096);
        assert!(e.eval_excess <= TOL, "{name}: eval off by {:.2e} relative beyond its conditioning", e.eval_excess);
        assert!(e.pdf <= TOL, "{name}: pdf off by {:.2e} relative", e.pdf);
        assert!(e.sample_pdf <= TOL, "{name}: sample pdf off by {:.2e} relative beyond its conditioning", e.sample_pdf);
        assert!(e.weight_excess <= TOL, "{name}: sample weight off by {:.2e} relative beyond its conditioning", e.weight_excess);
        assert!(e.sample_mismatch * 1000 <= e.pairs, "{name}: {} samples went elsewhere", e.sample_mismatch);
    }

    fn gpu_or_skip() -> Option<Gpu> {
        match Gpu::new() {
            Ok(g) => {
                println!("adapter: {}", g.adapter);
                Some(g)
            }
            Err(reason) => {
                eprintln!("SKIPPED: {reason}");
                None
            }
        }
    }

    #[test]
    fn every_model_kind_agrees_with_the_core_on_the_adapter() {
        let Some(gpu) = gpu_or_skip() else { return };
        let only = std::env::var("NBRDF_SHADER_ONLY").unwrap_or_default();
        for (m, storage) in common::all_models().iter().zip([Storage::Inline, DEFAULT_BUFFER].into_iter().cycle()) {
            if !m.name.contains(&only) {
                continue;
            }
            let buf = ModelBuf::from_bytes(&m.bytes).unwrap();
            let model = buf.model();
            let shader = export(&m.name, &m.bytes, &Options { storage: Some(storage), ..Options::default() }).unwrap();
            let mut rng = Rng(7);
            let k = model.position_len();
            let mut queries = Vec::new();
            let points = if k == 0 { 1 } else { 3 };
            for _ in 0..points {
                let p: Vec<f32> = (0..k).map(|_| 2.0 * rng.next() - 1.0).map(|v| if k == 3 { v * 0.57 } else { v }).collect();
                for (wi, wo) in pairs(&mut rng, 4200 / points / 2) {
                    queries.push((wi, wo, [rng.next(), rng.next(), rng.next()], p.clone()));
                }
            }
            let core = |q: &(Vec3, Vec3, [f32; 3], Vec<f32>)| {
                let prepared = model.prepare(&q.3).unwrap();
                (model.eval(&prepared, q.0, q.1), model.pdf(&prepared, q.0, q.1), model.sample(&prepared, q.1, q.2))
            };
            let exact = model.header().reciprocity == Reciprocity::Exact && !matches!(model.header().kind, nbrdf::file::ModelKind::Parametric(_));
            let seams = !matches!(model.header().kind, nbrdf::file::ModelKind::Parametric(_));
            let e = compare(&gpu, &shader, &queries, &core, exact, seams);
            check(&format!("{} ({storage:?})", m.name), &e);
        }
    }

    #[test]
    fn nbrdf_json_networks_and_paper_size_models_agree_on_the_adapter() {
        let Some(gpu) = gpu_or_skip() else { return };
        let json = common::json_network(3);
        let net = NbrdfNetwork::from_json_bytes(&json).unwrap();
        let proxy = *net.proxy();
        for storage in [Storage::Inline, DEFAULT_BUFFER] {
            let options = Options { storage: Some(storage), json_proxy: Some(proxy), ..Options::default() };
            let shader = export("random.json", &json, &options).unwrap();
            let mut rng = Rng(11);
            let queries: Vec<_> = pairs(&mut rng, 2100).into_iter().map(|(a, b)| (a, b, [rng.next(), rng.next(), rng.next()], vec![])).collect();
            let core = |q: &(Vec3, Vec3, [f32; 3], Vec<f32>)| (net.eval(q.0, q.1), proxy.pdf(q.0, q.1), proxy.sample(q.1, q.2, |wi, wo| net.eval(wi, wo)));
            check(&format!("NBRDF-json 6-21-21-3 ({storage:?})"), &compare(&gpu, &shader, &queries, &core, false, false));
        }
        // Without a proxy in the options the network samples through its own per-view table.
        let shader = export("random.json", &json, &Options::default()).unwrap();
        let mut rng = Rng(12);
        let queries: Vec<_> = pairs(&mut rng, 2100).into_iter().map(|(a, b)| (a, b, [rng.next(), rng.next(), rng.next()], vec![])).collect();
        let core = |q: &(Vec3, Vec3, [f32; 3], Vec<f32>)| (net.eval(q.0, q.1), Brdf::pdf(&net, q.0, q.1), Brdf::sample(&net, q.1, q.2));
        check("NBRDF-json 6-21-21-3, per-view table", &compare(&gpu, &shader, &queries, &core, false, false));
        // The paper's architecture itself (width 128): through the storage buffer.
        use nbrdf::file::{ModelHeader, ModelKind, PositionEncoding, Precision};
        let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 8 }, 4);
        let m = common::model("paper AdditiveShared enhanced Exact", h, Precision::F16, 5);
        let buf = ModelBuf::from_bytes(&m.bytes).unwrap();
        let model = buf.model();
        let shader = export(&m.name, &m.bytes, &Options::default()).unwrap();
        assert_eq!(shader.storage, DEFAULT_BUFFER, "a paper-size network goes to the storage buffer");
        let mut rng = Rng(13);
        let p: Vec<f32> = (0..8).map(|_| rng.next() - 0.5).collect();
        let queries: Vec<_> = pairs(&mut rng, 2100).into_iter().map(|(a, b)| (a, b, [rng.next(), rng.next(), rng.next()], p.clone())).collect();
        let core = |q: &(Vec3, Vec3, [f32; 3], Vec<f32>)| {
            let prepared = model.prepare(&q.3).unwrap();
            (model.eval(&prepared, q.0, q.1), model.pdf(&prepared, q.0, q.1), model.sample(&prepared, q.1, q.2))
        };
        check(&m.name, &compare(&gpu, &shader, &queries, &core, true, true));
    }
}
