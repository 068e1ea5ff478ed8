//! The compute entry point the tests run: evaluates, samples and takes the pdf of a batch of queries
//! from one storage buffer into another.

use std::fmt::Write;

/// Its name.
pub const TEST_ENTRY: &str = "nbrdf_test_main";
/// Values per query in the input buffer before the position input: wi (3), wo (3), u (3).
pub const TEST_IN_STRIDE_BASE: usize = 9;
/// Values per query in the output buffer: eval (3), pdf(wi, wo) (1), then the sample's wi (3), pdf
/// (1), weight (3) and ok (1, as 0 or 1).
pub const TEST_OUT_STRIDE: usize = 12;

/// The entry point of a model whose position input has `k` values (appended to each query's input).
pub(crate) fn test_entry(k: usize) -> String {
    let stride = TEST_IN_STRIDE_BASE + k;
    let mut s = String::new();
    let _ = write!(
        s,
        "// ---- test harness: query i reads nbrdf_test_in[{stride} i ..] = wi, wo, u{p_in}, and writes\n\
         // nbrdf_test_out[{out} i ..] = eval (3), pdf (1), sample wi (3), sample pdf (1), weight (3), ok (1).\n\
         @group(0) @binding(0) var<storage, read> nbrdf_test_in: array<f32>;\n\
         @group(0) @binding(1) var<storage, read_write> nbrdf_test_out: array<f32>;\n\n\
         @compute @workgroup_size(64)\n\
         fn {name}(@builtin(global_invocation_id) id: vec3<u32>) {{\n\
         \x20   let i = id.x;\n\
         \x20   if (i >= arrayLength(&nbrdf_test_out) / {out}u) {{\n        return;\n    }}\n\
         \x20   let b = i * {stride}u;\n\
         \x20   let wi = vec3<f32>(nbrdf_test_in[b], nbrdf_test_in[b + 1u], nbrdf_test_in[b + 2u]);\n\
         \x20   let wo = vec3<f32>(nbrdf_test_in[b + 3u], nbrdf_test_in[b + 4u], nbrdf_test_in[b + 5u]);\n\
         \x20   let u = vec3<f32>(nbrdf_test_in[b + 6u], nbrdf_test_in[b + 7u], nbrdf_test_in[b + 8u]);\n",
        p_in = if k > 0 { ", p" } else { "" },
        out = TEST_OUT_STRIDE,
        name = TEST_ENTRY,
    );
    let arg = if k > 0 {
        let _ = writeln!(
            s,
            "    var p: array<f32, {k}>;\n    for (var j = 0u; j < {k}u; j++) {{\n        p[j] = nbrdf_test_in[b + {}u + j];\n    }}",
            TEST_IN_STRIDE_BASE
        );
        ", p"
    } else {
        ""
    };
    let _ = write!(
        s,
        "    let f = nbrdf_eval(wi, wo{arg});\n\
         \x20   let pdf = nbrdf_pdf(wi, wo{arg});\n\
         \x20   let smp = nbrdf_sample(wo, u{arg});\n\
         \x20   let o = i * {out}u;\n\
         \x20   nbrdf_test_out[o] = f.x;\n\
         \x20   nbrdf_test_out[o + 1u] = f.y;\n\
         \x20   nbrdf_test_out[o + 2u] = f.z;\n\
         \x20   nbrdf_test_out[o + 3u] = pdf;\n\
         \x20   nbrdf_test_out[o + 4u] = smp.wi.x;\n\
         \x20   nbrdf_test_out[o + 5u] = smp.wi.y;\n\
         \x20   nbrdf_test_out[o + 6u] = smp.wi.z;\n\
         \x20   nbrdf_test_out[o + 7u] = smp.pdf;\n\
         \x20   nbrdf_test_out[o + 8u] = smp.weight.x;\n\
         \x20   nbrdf_test_out[o + 9u] = smp.weight.y;\n\
         \x20   nbrdf_test_out[o + 10u] = smp.weight.z;\n\
         \x20   nbrdf_test_out[o + 11u] = select(0.0, 1.0, smp.ok);\n}}\n",
        out = TEST_OUT_STRIDE,
    );
    s
}
