//! Measured materials: MERL `.binary` tables and NBRDF-json networks, read, written, looked up, and
//! rejected with a specific error when malformed.
//!
//! The NBRDF-json checks use the real networks in `$NBRDF_DATA/nbrdf-merl` (default `../shared/data`) and
//! skip with a message where that directory is absent.

use std::path::PathBuf;

use nbrdf::angles::{from_rusinkiewicz, rusinkiewicz_angles, Rusinkiewicz};
use nbrdf::measured::merl::{
    MerlTable, CHANNEL_SCALES, FILE_BYTES, HEADER_BYTES, INVALID, PHI_D_BINS, SAMPLES_PER_CHANNEL,
    THETA_D_BINS, THETA_H_BINS,
};
use nbrdf::measured::{Lookup, NbrdfNetwork};
use nbrdf::{Error, Rgb, Vec3};

const PI: f32 = core::f32::consts::PI;

// ---------------------------------------------------------------------------------------------------
// Helpers

/// A fresh, empty directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("nbrdf-measured-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `$NBRDF_DATA/nbrdf-merl`, or `None` (with a message) when absent.
fn nbrdf_merl_dir() -> Option<PathBuf> {
    let root = std::env::var_os("NBRDF_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| "../shared/data".into());
    let dir = root.join("nbrdf-merl");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipping: {} not found (set NBRDF_DATA to the shared data directory)",
            dir.display()
        );
        None
    }
}

/// A valid MERL file: header then `3 × 90 × 90 × 180` copies of `value`.
fn merl_bytes(value: f64) -> Vec<u8> {
    let mut b = Vec::with_capacity(FILE_BYTES);
    for n in [90i32, 90, 180] {
        b.extend_from_slice(&n.to_le_bytes());
    }
    for _ in 0..3 * SAMPLES_PER_CHANNEL {
        b.extend_from_slice(&value.to_le_bytes());
    }
    b
}

/// A smooth, coloured, isotropic and reciprocal test BRDF.
fn smooth_brdf(wi: Vec3, wo: Vec3) -> Rgb {
    let h = (wi + wo).normalize();
    [
        0.2 + h.z * h.z,
        0.1 + wi.z * wo.z,
        0.05 + (wi.z - wo.z) * (wi.z - wo.z),
    ]
}

fn close(a: Rgb, b: Rgb, rel: f32) -> bool {
    a.iter()
        .zip(&b)
        .all(|(x, y)| (x - y).abs() <= rel * y.abs().max(1e-3))
}

// ---------------------------------------------------------------------------------------------------
// MERL: bins

#[test]
fn merl_bins_match_hand_computed_reference_indices() {
    // θh: ⌊sqrt(θh / (π/2)) · 90⌋. 0.01 / (π/2) = 0.0063662, sqrt = 0.079789, · 90 = 7.18.
    assert_eq!(MerlTable::bins(0.01, 0.0, 0.0)[0], 7);
    // 1.0 / (π/2) = 0.63662, sqrt = 0.797885, · 90 = 71.81.
    assert_eq!(MerlTable::bins(1.0, 0.0, 0.0)[0], 71);
    // The ends: θh ≤ 0 is bin 0, θh = π/2 would be 90 and clamps to 89.
    assert_eq!(MerlTable::bins(-0.1, 0.0, 0.0)[0], 0);
    assert_eq!(MerlTable::bins(PI / 2.0, 0.0, 0.0)[0], 89);

    // θd: ⌊θd / (π/2) · 90⌋. 0.3 → 17.19, 1.5 → 85.94, beyond π/2 clamps.
    assert_eq!(MerlTable::bins(0.0, 0.3, 0.0)[1], 17);
    assert_eq!(MerlTable::bins(0.0, 1.5, 0.0)[1], 85);
    assert_eq!(MerlTable::bins(0.0, 2.0, 0.0)[1], 89);

    // φd: folded by π, then ⌊φ / π · 180⌋. 1.0 → 57.30; -0.5 → π - 0.5 = 2.6416 → 151.35;
    // 6.0 → 6 - π = 2.8584 → 163.77.
    assert_eq!(MerlTable::bins(0.0, 0.0, 1.0)[2], 57);
    assert_eq!(MerlTable::bins(0.0, 0.0, 1.0 + PI)[2], 57);
    assert_eq!(MerlTable::bins(0.0, 0.0, -0.5)[2], 151);
    assert_eq!(MerlTable::bins(0.0, 0.0, 6.0)[2], 163);

    // Flat index iφd + 180 (iθd + 90 iθh): (7, 17, 57) → 57 + 180 · 647 = 116517.
    assert_eq!(MerlTable::index(0.01, 0.3, 1.0), 116_517);
    assert_eq!(
        MerlTable::index(PI / 2.0, PI / 2.0, PI - 1e-4),
        SAMPLES_PER_CHANNEL - 1
    );
    // Non-finite angles land in bin 0 rather than out of range.
    assert_eq!(
        MerlTable::bins(f32::NAN, f32::INFINITY, f32::NAN),
        [0, 89, 0]
    );
}

#[test]
fn merl_bin_centres_fall_inside_their_bins() {
    for ih in [0, 1, 44, 89] {
        for id in [0, 45, 89] {
            for ip in [0, 90, 179] {
                let [th, td, pd] = MerlTable::bin_centre(ih, id, ip);
                assert_eq!(MerlTable::bins(th, td, pd), [ih, id, ip]);
            }
        }
    }
    // The first θh centre is ((0.5 / 90)² · π/2).
    let [th, _, _] = MerlTable::bin_centre(0, 0, 0);
    assert!((th - (0.5f32 / 90.0).powi(2) * PI / 2.0).abs() < 1e-10);
}

// ---------------------------------------------------------------------------------------------------
// MERL: files

#[test]
fn merl_write_then_read_is_bit_exact_and_leaves_no_temporary_file() {
    // Values a real file holds: ordinary samples, the invalid marker, zero, negative zero, a subnormal.
    let mut raw = Vec::with_capacity(3 * SAMPLES_PER_CHANNEL);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for i in 0..3 * SAMPLES_PER_CHANNEL {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        raw.push(match i % 7 {
            0 => INVALID,
            1 => 0.0,
            2 => -0.0,
            3 => f64::MIN_POSITIVE / 3.0,
            _ => (state >> 11) as f64 / (1u64 << 53) as f64 * 3000.0,
        });
    }
    let table = MerlTable::from_raw(raw).unwrap();
    let dir = TempDir::new("roundtrip");
    let path = dir.0.join("noise.binary");
    table.write(&path).unwrap();

    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes.len(), FILE_BYTES);
    assert_eq!(
        &bytes[..HEADER_BYTES],
        &[90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0]
    );
    let back = MerlTable::read(&path).unwrap();
    let bits = |t: &MerlTable| t.raw().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back), bits(&table));
    assert_eq!(back.to_bytes(), bytes);

    // Overwriting goes through a temporary file too; afterwards only the target is in the directory.
    table.write(&path).unwrap();
    let names: Vec<_> = std::fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["noise.binary"]);
}

#[test]
fn merl_lookup_of_a_tabulated_function_returns_it_at_bin_centres() {
    let table = MerlTable::tabulate(smooth_brdf);
    let mut valid = 0;
    for ih in (0..THETA_H_BINS).step_by(7) {
        for id in (0..THETA_D_BINS).step_by(5) {
            for ip in (0..PHI_D_BINS).step_by(11) {
                let [theta_h, theta_d, phi_d] = MerlTable::bin_centre(ih, id, ip);
                let (wi, wo) = from_rusinkiewicz(&Rusinkiewicz {
                    theta_h,
                    phi_h: 0.0,
                    theta_d,
                    phi_d,
                });
                let stored = table.sample(MerlTable::index(theta_h, theta_d, phi_d));
                if wi.z > 0.0 && wo.z > 0.0 {
                    valid += 1;
                    let f = smooth_brdf(wi, wo);
                    assert!(
                        close(table.eval(wi, wo), f, 1e-6),
                        "nearest at ({ih}, {id}, {ip})"
                    );
                    let g = table.eval_trilinear(wi, wo);
                    assert!(
                        close(g, f, 1e-3),
                        "trilinear at ({ih}, {id}, {ip}): {g:?} vs {f:?}"
                    );
                    assert!(close(stored.unwrap(), f, 1e-6));
                    // Rotating the pair about the normal (φh) changes nothing for an isotropic table.
                    let (wi2, wo2) = from_rusinkiewicz(&Rusinkiewicz {
                        theta_h,
                        phi_h: 2.0,
                        theta_d,
                        phi_d,
                    });
                    assert!(close(table.eval(wi2, wo2), f, 1e-6));
                } else {
                    // Below the horizon: stored as invalid, evaluated as 0.
                    assert_eq!(stored, None);
                    assert_eq!(table.eval(wi, wo), [0.0; 3]);
                }
            }
        }
    }
    assert!(valid > 300, "only {valid} valid bins checked");
}

#[test]
fn merl_trilinear_is_exact_for_functions_linear_in_the_bin_coordinates() {
    // f = 0.5 + θd / 2 is linear in the θd bin coordinate and constant in the others.
    let f = |wi: Vec3, wo: Vec3| {
        let td = rusinkiewicz_angles(wi, wo).map_or(0.0, |a| a[1]);
        [0.5 + 0.5 * td; 3]
    };
    let table = MerlTable::tabulate(f);
    let mut worst_nearest = 0.0f32;
    for k in 0..200 {
        let t = k as f32 / 200.0;
        // Interior of the θd range (past the first centre), away from the horizon.
        let r = Rusinkiewicz {
            theta_h: 0.45 * t,
            phi_h: 0.7,
            theta_d: 0.02 + 0.95 * t,
            phi_d: 6.2 * t,
        };
        let (wi, wo) = from_rusinkiewicz(&r);
        let expect = 0.5 + 0.5 * r.theta_d;
        let got = table.eval_trilinear(wi, wo);
        assert!(
            (got[0] - expect).abs() < 2e-5,
            "θd = {}: {} vs {expect}",
            r.theta_d,
            got[0]
        );
        worst_nearest = worst_nearest.max((table.eval(wi, wo)[0] - expect).abs());
    }
    // The nearest lookup is off by up to half a bin of slope: 0.5 · (π/2) / 90 / 2 ≈ 0.0044.
    assert!(
        worst_nearest > 1e-3 && worst_nearest < 0.0045,
        "{worst_nearest}"
    );
}

#[test]
fn merl_trilinear_wraps_phi_d_with_period_pi() {
    // f depends on φd only through cos(2 φd): periodic with period π like the table.
    let table = MerlTable::tabulate(|wi, wo| {
        let pd = rusinkiewicz_angles(wi, wo).map_or(0.0, |a| a[2]);
        [1.0 + 0.5 * libm::cosf(2.0 * pd); 3]
    });
    for phi_d in [0.0005, PI - 0.0005, PI + 0.0005, 2.0 * PI - 0.0005] {
        let got = table.eval_angles(0.2, 0.5, phi_d, Lookup::Trilinear)[0];
        // Between the centres at ±π/360 the interpolant is 1 + 0.5 cos(π/180) = 1.49992.
        assert!((got - 1.499_924).abs() < 1e-4, "φd = {phi_d}: {got}");
    }
}

#[test]
fn merl_lookups_are_exactly_reciprocal() {
    let table = MerlTable::tabulate(smooth_brdf);
    for k in 0..100 {
        let a = k as f32 * 0.37;
        let wi = Vec3::new(
            libm::cosf(a) * 0.6,
            libm::sinf(a) * 0.5,
            0.3 + 0.006 * k as f32,
        );
        let wo = Vec3::new(-0.2 + 0.004 * k as f32, 0.45, 0.8);
        for lookup in [Lookup::Nearest, Lookup::Trilinear] {
            let f = table.eval_with(wi, wo, lookup);
            let g = table.eval_with(wo, wi, lookup);
            assert_eq!(f.map(f32::to_bits), g.map(f32::to_bits));
        }
    }
}

#[test]
fn merl_scales_channels_and_reads_negative_entries_as_zero() {
    let mut raw = vec![1500.0; 3 * SAMPLES_PER_CHANNEL];
    let i = MerlTable::index(0.3, 0.4, 0.5);
    raw[SAMPLES_PER_CHANNEL + i] = -1.0; // green of one bin invalid
    let table = MerlTable::from_raw(raw).unwrap();
    let scaled = CHANNEL_SCALES.map(|s| (1500.0 * s) as f32);
    assert_eq!(scaled, [1.0, 1.15, 1.66]);
    assert_eq!(table.eval_angles(0.6, 0.4, 0.5, Lookup::Nearest), scaled);
    assert_eq!(
        table.eval_angles(0.3, 0.4, 0.5, Lookup::Nearest),
        [1.0, 0.0, 1.66]
    );
    // Trilinear leaves the invalid corner out: a constant table stays constant.
    let g = table.eval_angles(0.3, 0.4, 0.5, Lookup::Trilinear);
    assert!((g[1] - 1.15).abs() < 1e-6, "{g:?}");
    assert_eq!(table.sample(i), None);
    // Below the horizon and NaN give 0.
    assert_eq!(table.eval(Vec3::new(0.0, 0.3, -0.2), Vec3::Z), [0.0; 3]);
    assert_eq!(table.eval(Vec3::new(f32::NAN, 0.0, 1.0), Vec3::Z), [0.0; 3]);
}

#[test]
fn merl_malformed_files_get_specific_errors() {
    // Truncated header.
    assert_eq!(
        MerlTable::from_bytes(&[90, 0, 0, 0, 90, 0]),
        Err(Error::Truncated {
            what: "MERL header",
            needed: 12,
            got: 6
        })
    );
    let good = merl_bytes(1.0);
    assert!(MerlTable::from_bytes(&good).is_ok());

    // Truncated samples: one byte short, and the header alone.
    assert_eq!(
        MerlTable::from_bytes(&good[..FILE_BYTES - 1]),
        Err(Error::Truncated {
            what: "MERL samples",
            needed: FILE_BYTES,
            got: FILE_BYTES - 1
        })
    );
    assert!(matches!(
        MerlTable::from_bytes(&good[..12]),
        Err(Error::Truncated { got: 12, .. })
    ));

    // Trailing data.
    let mut long = good.clone();
    long.push(0);
    assert!(matches!(
        MerlTable::from_bytes(&long),
        Err(Error::SizeMismatch { expected: FILE_BYTES, found, .. }) if found == FILE_BYTES + 1
    ));

    // Wrong dimensions: the reference's 360 φd bins, swapped θ/φ order, a negative count.
    let mut dims = good.clone();
    dims[8..12].copy_from_slice(&360i32.to_le_bytes());
    assert_eq!(
        MerlTable::from_bytes(&dims),
        Err(Error::SizeMismatch {
            what: "MERL header phi_d bin count",
            expected: 180,
            found: 360
        })
    );
    let mut swapped = good.clone();
    swapped[0..4].copy_from_slice(&180i32.to_le_bytes());
    swapped[8..12].copy_from_slice(&90i32.to_le_bytes());
    assert_eq!(
        MerlTable::from_bytes(&swapped),
        Err(Error::SizeMismatch {
            what: "MERL header theta_h bin count",
            expected: 90,
            found: 180
        })
    );
    let mut negative = good.clone();
    negative[4..8].copy_from_slice(&(-90i32).to_le_bytes());
    assert_eq!(
        MerlTable::from_bytes(&negative),
        Err(Error::InvalidValue {
            what: "MERL header theta_d bin count",
            reason: "negative bin count"
        })
    );

    // NaN and infinite samples, with their index.
    let mut nan = good.clone();
    let k = 1_000_003;
    nan[12 + 8 * k..12 + 8 * k + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    assert_eq!(
        MerlTable::from_bytes(&nan),
        Err(Error::NonFinite {
            what: "MERL samples",
            index: k
        })
    );
    let mut inf = good;
    inf[12..20].copy_from_slice(&f64::NEG_INFINITY.to_le_bytes());
    assert_eq!(
        MerlTable::from_bytes(&inf),
        Err(Error::NonFinite {
            what: "MERL samples",
            index: 0
        })
    );

    // Raw values of the wrong count or with NaN.
    assert!(matches!(
        MerlTable::from_raw(vec![0.0; 10]),
        Err(Error::SizeMismatch { found: 10, .. })
    ));
    let mut raw = vec![0.0; 3 * SAMPLES_PER_CHANNEL];
    raw[7] = f64::NAN;
    assert_eq!(
        MerlTable::from_raw(raw),
        Err(Error::NonFinite {
            what: "MERL samples",
            index: 7
        })
    );
}

#[test]
fn merl_missing_and_unwritable_paths_are_io_errors() {
    let dir = TempDir::new("io");
    let missing = dir.0.join("absent.binary");
    match MerlTable::read(&missing) {
        Err(Error::Io { path, kind, .. }) => {
            assert_eq!(path, missing);
            assert_eq!(kind, std::io::ErrorKind::NotFound);
        }
        other => panic!("expected an I/O error, got {other:?}"),
    }
    // A file with trailing data is rejected before it is read whole, naming the file and its length.
    let big = dir.0.join("big.binary");
    std::fs::write(&big, vec![0u8; FILE_BYTES + 8]).unwrap();
    match MerlTable::read(&big) {
        Err(Error::Context { what, message }) => {
            assert_eq!(what, format!("MERL file {}", big.display()));
            assert!(message.contains("trailing data") && message.contains(&(FILE_BYTES + 8).to_string()), "{message}");
        }
        other => panic!("expected the file named, got {other:?}"),
    }
    // A device that never ends is read no further than a table.
    #[cfg(unix)]
    assert!(MerlTable::read("/dev/zero").unwrap_err().to_string().contains("/dev/zero"));

    // Writing into a directory that does not exist fails and creates nothing.
    let table = MerlTable::from_raw(vec![0.0; 3 * SAMPLES_PER_CHANNEL]).unwrap();
    let target = dir.0.join("no-such-dir").join("t.binary");
    assert!(matches!(table.write(&target), Err(Error::Io { .. })));
    assert!(!target.exists());
}

// ---------------------------------------------------------------------------------------------------
// NBRDF-json: real data

#[test]
fn nbrdf_json_reference_values() {
    let Some(dir) = nbrdf_merl_dir() else { return };
    // Reference values from ../shared/data/README.md, recomputed in f64 from the JSON:
    // chrome (501.878, 543.792, 542.821), white-diffuse-bball (0.147390, 0.131070, 0.104293).
    let chrome = NbrdfNetwork::load(dir.join("chrome.json")).unwrap();
    assert_eq!(chrome.name(), "chrome");
    assert_eq!(chrome.widths(), [6, 21, 21, 3]);
    let f = chrome.eval_angles(0.0, 0.3, 1.0);
    assert!(close(f, [501.878, 543.792, 542.821], 1e-4), "{f:?}");

    let white = NbrdfNetwork::load(dir.join("white-diffuse-bball.json")).unwrap();
    let f = white.eval_angles(0.0, 0.3, 1.0);
    assert!(close(f, [0.147_390, 0.131_070, 0.104_293], 1e-4), "{f:?}");

    // eval(wi, wo) finds the angles itself: (θh, θd, φd) = (0.2, 0.3, 1), any φh. Reference value
    // computed in f64 from the JSON: (0.119505, 0.105193, 0.069349).
    let (wi, wo) = from_rusinkiewicz(&Rusinkiewicz {
        theta_h: 0.2,
        phi_h: 0.4,
        theta_d: 0.3,
        phi_d: 1.0,
    });
    let f = white.eval(wi, wo);
    assert!(close(f, [0.119_505, 0.105_193, 0.069_349], 1e-4), "{f:?}");
    assert_eq!(white.eval(Vec3::new(0.1, 0.0, -1.0), Vec3::Z), [0.0; 3]);
}

#[test]
fn nbrdf_json_all_hundred_materials_load_and_evaluate_finite() {
    let Some(dir) = nbrdf_merl_dir() else { return };
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let net = NbrdfNetwork::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(net.name(), path.file_stem().unwrap().to_str().unwrap());
        for i in 0..=8 {
            for j in 0..=8 {
                for k in 0..8 {
                    let th = i as f32 / 8.0 * PI / 2.0;
                    let td = j as f32 / 8.0 * PI / 2.0;
                    let f = net.eval_angles(th, td, k as f32 * PI / 4.0);
                    assert!(
                        f.iter().all(|c| c.is_finite() && *c >= 0.0),
                        "{}: {f:?}",
                        net.name()
                    );
                }
            }
        }
        n += 1;
    }
    assert_eq!(n, 100);
}

#[test]
fn merl_table_tabulated_from_a_network_reproduces_it() {
    // The dataset tooling's path: NBRDF network → MERL table → lookup.
    let Some(dir) = nbrdf_merl_dir() else { return };
    let net = NbrdfNetwork::load(dir.join("blue-metallic-paint.json")).unwrap();
    let table = MerlTable::tabulate(|wi, wo| net.eval(wi, wo));
    let [th, td, pd] = MerlTable::bin_centre(20, 30, 40);
    let (wi, wo) = from_rusinkiewicz(&Rusinkiewicz {
        theta_h: th,
        phi_h: 0.0,
        theta_d: td,
        phi_d: pd,
    });
    assert!(close(table.eval(wi, wo), net.eval(wi, wo), 1e-6));
}

// ---------------------------------------------------------------------------------------------------
// NBRDF-json: malformed documents

/// A valid 6-4-3 document with `edit` applied to its JSON value.
fn doc(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut v = serde_json::json!({
        "name": "test",
        "input": "rusinkiewicz_half_diff_vectors",
        "output": "expm1_clamped",
        "layers": [
            {"inputs": 6, "outputs": 4, "activation": "relu",
             "weight": vec![vec![0.1; 6]; 4], "bias": vec![0.0; 4]},
            {"inputs": 4, "outputs": 3, "activation": "none",
             "weight": vec![vec![0.2; 4]; 3], "bias": vec![-0.1; 3]},
        ]
    });
    edit(&mut v);
    v.to_string()
}

#[test]
fn nbrdf_json_malformed_documents_get_specific_errors() {
    let parse = |s: &str| NbrdfNetwork::from_json_str(s);
    assert!(parse(&doc(|_| {})).is_ok());

    // Missing field and wrong field type: serde's message names the field.
    let err = parse(&doc(|v| {
        v.as_object_mut().unwrap().remove("layers");
    }))
    .unwrap_err();
    assert!(
        matches!(&err, Error::Parse { message, .. } if message.contains("missing field `layers`")),
        "{err}"
    );
    let err = parse(&doc(|v| v["layers"][0]["outputs"] = "four".into())).unwrap_err();
    assert!(
        matches!(&err, Error::Parse { message, .. } if message.contains("invalid type")),
        "{err}"
    );

    // NaN is not JSON: serde_json rejects it.
    let nan = doc(|_| {}).replacen("0.1", "NaN", 1);
    assert!(matches!(parse(&nan), Err(Error::Parse { .. })));
    // A number beyond f32 is finite JSON but not a usable weight.
    let huge = doc(|v| v["layers"][1]["weight"][2][1] = 1e39.into());
    assert_eq!(
        parse(&huge),
        Err(Error::NonFinite {
            what: "NBRDF-json weight",
            index: 9
        })
    );

    // Unknown activation, input and output.
    assert_eq!(
        parse(&doc(|v| v["layers"][0]["activation"] = "tanh".into())),
        Err(Error::InvalidValue {
            what: "NBRDF-json layer activation",
            reason: "expected \"relu\" or \"none\""
        })
    );
    assert!(matches!(
        parse(&doc(|v| v["input"] = "angles".into())),
        Err(Error::InvalidValue {
            what: "NBRDF-json input",
            ..
        })
    ));
    assert!(matches!(
        parse(&doc(|v| v["output"] = "exp".into())),
        Err(Error::InvalidValue {
            what: "NBRDF-json output",
            ..
        })
    ));

    // Wrong sizes.
    assert!(matches!(
        parse(&doc(
            |v| v["layers"][0]["bias"] = serde_json::json!([0.0, 0.0, 0.0])
        )),
        Err(Error::SizeMismatch {
            expected: 4,
            found: 3,
            ..
        })
    ));
    assert!(matches!(
        parse(&doc(
            |v| v["layers"][1]["weight"][1] = serde_json::json!([0.0, 0.0])
        )),
        Err(Error::SizeMismatch {
            expected: 4,
            found: 2,
            ..
        })
    ));
    assert!(matches!(
        parse(&doc(|v| v["layers"][0]["outputs"] = 5.into())),
        Err(Error::SizeMismatch {
            expected: 5,
            found: 4,
            ..
        })
    ));
    assert!(matches!(
        parse(&doc(|v| v["layers"][1]["inputs"] = 5.into())),
        Err(Error::SizeMismatch {
            expected: 4,
            found: 5,
            ..
        })
    ));
    assert!(matches!(
        parse(&doc(|v| v["layers"][0]["inputs"] = 7.into())),
        Err(Error::SizeMismatch {
            expected: 6,
            found: 7,
            ..
        })
    ));
    let two_outputs = doc(|v| {
        v["layers"][1]["outputs"] = 2.into();
        v["layers"][1]["weight"] = serde_json::json!(vec![vec![0.2; 4]; 2]);
        v["layers"][1]["bias"] = serde_json::json!([0.0, 0.0]);
    });
    assert_eq!(
        parse(&two_outputs),
        Err(Error::SizeMismatch {
            what: "NBRDF-json last layer outputs (RGB)",
            expected: 3,
            found: 2
        })
    );
    assert!(matches!(
        parse(&doc(|v| v["layers"][0]["outputs"] = 1000.into())),
        Err(Error::TooLarge {
            found: 1000,
            max: 64,
            ..
        })
    ));
    assert!(matches!(
        parse(&doc(|v| v["layers"] = serde_json::json!([]))),
        Err(Error::InvalidValue {
            what: "NBRDF-json layers",
            ..
        })
    ));

    // Not JSON at all; not UTF-8.
    assert!(matches!(parse("{\"layers\": ["), Err(Error::Parse { .. })));
    assert!(matches!(
        NbrdfNetwork::from_json_bytes(&[0xff, 0xfe, b'{']),
        Err(Error::Parse { .. })
    ));
}

#[test]
fn nbrdf_json_missing_file_is_an_io_error_and_parse_errors_name_the_file() {
    let dir = TempDir::new("json");
    let missing = dir.0.join("absent.json");
    assert!(matches!(
        NbrdfNetwork::load(&missing),
        Err(Error::Io {
            kind: std::io::ErrorKind::NotFound,
            ..
        })
    ));
    let bad = dir.0.join("bad.json");
    std::fs::write(&bad, "{\"input\": 3}").unwrap();
    match NbrdfNetwork::load(&bad) {
        Err(Error::Parse { what, .. }) => assert!(what.contains("bad.json"), "{what}"),
        other => panic!("expected a parse error, got {other:?}"),
    }
}
