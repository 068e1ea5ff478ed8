//! The study's figures (PNG): the accuracy-versus-cost Pareto plots, and for a few jobs the reference
//! next to the model's rendering with the HDR-FLIP error map.
//!
//! Plots are drawn by `plotters` into an in-memory RGB buffer and written as PNG by the core's atomic
//! writer (`nbrdf_scene::image::write_png_rgb8`), like the study's other outputs.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use nbrdf_scene::image::{srgb8, write_png_rgb8, RgbImage};
use plotters::prelude::*;
use serde::Serialize;

use crate::metrics::flip::hdr_flip;
use crate::{Error, Result};

/// The font of every plot label: DejaVu Sans Mono (Bitstream Vera licence, trainer/assets/fonts),
/// embedded in the binary and handed to plotters' pure-Rust `ab_glyph` text backend. Embedding, rather
/// than plotters' default `ttf` backend, means no fontconfig and no system fonts: the figures render the
/// same on a clean CI machine as on a desktop.
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");

/// The family name the plots ask for.
const FAMILY: &str = "sans-serif";

/// Registers [`FONT`] with plotters once per process.
fn register_font() -> Result<()> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(Error::Invalid("the embedded plot font does not parse".into())) }
}

/// One labelled point of an accuracy-versus-cost plot: `cost` lower is better, `accuracy` higher.
#[derive(Clone, Debug, PartialEq)]
pub struct CostPoint {
    pub label: String,
    pub cost: f64,
    pub accuracy: f64,
}

/// Indices of the Pareto-optimal points, sorted by cost: those no other point dominates, where `a`
/// dominates `b` when `a` costs no more and is no less accurate, and is strictly better in one of the
/// two. Points with a non-finite coordinate are left out (neither on the front nor dominating). Of
/// exact duplicates both stay on the front, since neither is strictly better.
pub fn pareto_front(points: &[CostPoint]) -> Vec<usize> {
    let finite = |p: &CostPoint| p.cost.is_finite() && p.accuracy.is_finite();
    let dominates = |a: &CostPoint, b: &CostPoint| {
        a.cost <= b.cost && a.accuracy >= b.accuracy && (a.cost < b.cost || a.accuracy > b.accuracy)
    };
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| finite(&points[i]))
        .filter(|&i| !points.iter().any(|q| finite(q) && dominates(q, &points[i])))
        .collect();
    front.sort_by(|&a, &b| points[a].cost.total_cmp(&points[b].cost).then(points[b].accuracy.total_cmp(&points[a].accuracy)));
    front
}

/// Writes 8-bit RGB as a PNG, atomically (the core's writer), creating its folder.
fn write_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    write_png_rgb8(path, width, height, rgb).map_err(Error::Core)
}

/// Axis range of positive values on a log axis, padded by a quarter decade on both sides.
fn log_range(v: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = v.filter(|x| x.is_finite() && *x > 0.0).fold((f64::INFINITY, 0.0f64), |(l, h), x| (l.min(x), h.max(x)));
    if !lo.is_finite() {
        return 0.1..10.0;
    }
    lo / 10f64.powf(0.25)..hi * 10f64.powf(0.25)
}

/// Linear axis range padded by 8 % (at least ±0.5) on both sides.
fn lin_range(v: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = v.filter(|x| x.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x), h.max(x)));
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = ((hi - lo) * 0.08).max(0.5);
    lo - pad..hi + pad
}

/// The series' legend in a framed, half-transparent white box.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    font_size: u32,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .position(position)
        .label_font((FAMILY, font_size))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
}

/// Plots accuracy against cost (log axis) with every point labelled and the Pareto front drawn as a
/// step line through its points; writes a `900×600` PNG to `path`.
pub fn pareto_plot(path: &Path, title: &str, cost_label: &str, accuracy_label: &str, points: &[CostPoint]) -> Result<()> {
    register_font()?;
    let kept: Vec<&CostPoint> = points.iter().filter(|p| p.cost.is_finite() && p.cost > 0.0 && p.accuracy.is_finite()).collect();
    let (width, height) = (900u32, 600u32);
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    let plot_err = |e: &dyn std::fmt::Display| Error::Invalid(format!("plot {}: {e}", path.display()));
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&e))?;
        let xr = log_range(kept.iter().map(|p| p.cost));
        let yr = lin_range(kept.iter().map(|p| p.accuracy));
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FAMILY, 20))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(xr.log_scale(), yr)
            .map_err(|e| plot_err(&e))?;
        chart
            .configure_mesh()
            .x_desc(cost_label)
            .y_desc(accuracy_label)
            .label_style((FAMILY, 14))
            .draw()
            .map_err(|e| plot_err(&e))?;
        let owned: Vec<CostPoint> = kept.iter().map(|p| (*p).clone()).collect();
        let front = pareto_front(&owned);
        // The front as a staircase: from each front point, right at its accuracy to the next one's cost.
        let mut stairs = Vec::new();
        for (k, &i) in front.iter().enumerate() {
            stairs.push((owned[i].cost, owned[i].accuracy));
            if let Some(&j) = front.get(k + 1) {
                stairs.push((owned[j].cost, owned[i].accuracy));
            }
        }
        let red = RGBColor(200, 40, 40);
        chart
            .draw_series(LineSeries::new(stairs, red.stroke_width(2)))
            .map_err(|e| plot_err(&e))?
            .label("Pareto front")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], red.stroke_width(2)));
        chart
            .draw_series(owned.iter().enumerate().map(|(i, p)| {
                let colour = if front.contains(&i) { red } else { RGBColor(40, 70, 160) };
                // Labels alternate above and below their points, so that close pairs (a model and its
                // f16 copy) stay readable.
                let dy = if i % 2 == 0 { -16 } else { 5 };
                EmptyElement::at((p.cost, p.accuracy))
                    + Circle::new((0, 0), 4, colour.filled())
                    + Text::new(p.label.clone(), (6, dy), (FAMILY, 12).into_font().color(&BLACK))
            }))
            .map_err(|e| plot_err(&e))?;
        draw_legend(&mut chart, SeriesLabelPosition::UpperMiddle, 14).map_err(|e| plot_err(&e))?;
        root.present().map_err(|e| plot_err(&e))?;
    }
    write_png(path, width, height, &rgb)
}

/// One variant's learning curve: `(step, training seconds, test PSNR)` per point.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    pub label: String,
    pub points: Vec<(f64, f64, f64)>,
}

/// Distinct line colours (Okabe–Ito's colour-blind-safe set, then darker tones), cycled.
const PALETTE: [RGBColor; 10] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(230, 159, 0),
    RGBColor(0, 0, 0),
    RGBColor(120, 60, 20),
    RGBColor(90, 90, 160),
    RGBColor(150, 150, 150),
];

/// Plots test PSNR against training steps (left panel) and against training wall time (right
/// panel) for every curve; writes a `1400×560` PNG to `path`.
pub fn curve_plot(path: &Path, title: &str, curves: &[Curve]) -> Result<()> {
    register_font()?;
    let (width, height) = (1400u32, 560u32);
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    let plot_err = |e: &dyn std::fmt::Display| Error::Invalid(format!("plot {}: {e}", path.display()));
    let finite = |c: &Curve| c.points.iter().filter(|p| p.2.is_finite()).copied().collect::<Vec<_>>();
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&e))?;
        let root = root.titled(title, (FAMILY, 20)).map_err(|e| plot_err(&e))?;
        let panels = root.split_evenly((1, 2));
        let yr = lin_range(curves.iter().flat_map(|c| finite(c).into_iter().map(|p| p.2)));
        for (panel, by_time) in panels.iter().zip([false, true]) {
            let x = |p: &(f64, f64, f64)| if by_time { p.1 } else { p.0 };
            let xmax = curves.iter().flat_map(|c| finite(c).into_iter().map(|p| x(&p))).fold(0.0f64, f64::max).max(1e-9);
            let mut chart = ChartBuilder::on(panel)
                .margin(14)
                .x_label_area_size(40)
                .y_label_area_size(56)
                .build_cartesian_2d(0.0..xmax * 1.02, yr.clone())
                .map_err(|e| plot_err(&e))?;
            chart
                .configure_mesh()
                .x_desc(if by_time { "training wall time (s)" } else { "training step" })
                .y_desc("test PSNR (dB)")
                .label_style((FAMILY, 14))
                .draw()
                .map_err(|e| plot_err(&e))?;
            for (i, c) in curves.iter().enumerate() {
                let colour = PALETTE[i % PALETTE.len()];
                let pts: Vec<(f64, f64)> = finite(c).iter().map(|p| (x(p), p.2)).collect();
                chart
                    .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
                    .map_err(|e| plot_err(&e))?
                    .label(c.label.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
            }
            draw_legend(&mut chart, SeriesLabelPosition::LowerRight, 12).map_err(|e| plot_err(&e))?;
        }
        root.present().map_err(|e| plot_err(&e))?;
    }
    write_png(path, width, height, &rgb)
}

/// Enlargement of the comparison images: the study renders small (64²), too small to inspect.
pub const ZOOM: u32 = 4;

/// Pixels of `images` (each `width × height`) enlarged [`ZOOM`]× by pixel replication and placed side
/// by side with a 4-pixel white gap; returns the total width and height and the 8-bit RGB rows.
fn side_by_side(images: &[Vec<[u8; 3]>], width: u32, height: u32) -> (u32, u32, Vec<u8>) {
    let gap = 4u32;
    let (w, h) = (width * ZOOM, height * ZOOM);
    let n = images.len() as u32;
    let total = n * w + n.saturating_sub(1) * gap;
    let mut rgb = vec![255u8; (total * h * 3) as usize];
    for (k, img) in images.iter().enumerate() {
        let x0 = k as u32 * (w + gap);
        for row in 0..h {
            for col in 0..w {
                let o = ((row * total + x0 + col) * 3) as usize;
                rgb[o..o + 3].copy_from_slice(&img[((row / ZOOM) * width + col / ZOOM) as usize]);
            }
        }
    }
    (total, h, rgb)
}

/// The FLIP map colour of an error in [0, 1]: the reference tool's magma map (`flip_rs::MAGMA`,
/// 256 sRGB entries), index `round(255 e)` as `FLIP::tensor::colorMap`.
pub fn magma(e: f32) -> [u8; 3] {
    let e = if e.is_finite() { e.clamp(0.0, 1.0) } else { 1.0 };
    flip_rs::MAGMA[(e * 255.0 + 0.5) as usize].map(|c| (c * 255.0).round() as u8)
}

/// One rendered comparison, for the report.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    pub scene: String,
    pub model: String,
    /// Reference | model rendering (sRGB PNG), relative to the study folder.
    pub images: PathBuf,
    /// HDR-FLIP error map (magma PNG), relative to the study folder.
    pub flip_map: PathBuf,
    /// Mean HDR-FLIP of this image over the object.
    pub flip_mean: f64,
}

/// Writes `figures/<scene>__<model>.png` (reference | rendering) and `…-flip.png` (the HDR-FLIP map of
/// the rendering against the reference, masked as in the metrics) under `out`.
pub fn write_comparison(
    out: &Path,
    scene: &str,
    model: &str,
    reference: &RgbImage,
    rendering: &RgbImage,
    mask: &[bool],
) -> Result<Comparison> {
    let (w, h) = (reference.width, reference.height);
    if (rendering.width, rendering.height) != (w, h) || mask.len() != reference.data.len() {
        return Err(Error::Invalid(format!("comparison {scene} / {model}: reference, rendering and mask differ in size")));
    }
    let stem = format!("{scene}__{}", model.replace('+', "_"));
    let images = PathBuf::from("figures").join(format!("{stem}.png"));
    let flip_map = PathBuf::from("figures").join(format!("{stem}-flip.png"));
    let to8 = |img: &RgbImage| img.data.iter().map(|p| p.map(srgb8)).collect::<Vec<_>>();
    let (tw, th, rgb) = side_by_side(&[to8(reference), to8(rendering)], w, h);
    write_png(&out.join(&images), tw, th, &rgb)?;
    let flip = hdr_flip(reference, rendering, Some(mask));
    let map: Vec<[u8; 3]> = flip.map.iter().map(|&e| magma(e)).collect();
    let (mw, mh, map) = side_by_side(&[map], w, h);
    write_png(&out.join(&flip_map), mw, mh, &map)?;
    Ok(Comparison { scene: scene.into(), model: model.into(), images, flip_map, flip_mean: flip.mean })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(cost: f64, accuracy: f64) -> CostPoint {
        CostPoint { label: format!("{cost}/{accuracy}"), cost, accuracy }
    }

    /// The defining property on a scatter of points with ties: nothing on the front is dominated, and
    /// everything off it (finite) is dominated by some point.
    #[test]
    fn pareto_front_is_exactly_the_non_dominated_set() {
        let mut pts = Vec::new();
        let mut s = 12345u64;
        for _ in 0..200 {
            // xorshift; coarse values so that ties in either coordinate occur.
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            pts.push(p((s % 17) as f64 + 1.0, ((s >> 20) % 13) as f64));
        }
        pts.push(p(f64::NAN, 100.0));
        let front = pareto_front(&pts);
        let dominated = |b: &CostPoint| {
            pts.iter().any(|a| {
                a.cost.is_finite()
                    && a.cost <= b.cost
                    && a.accuracy >= b.accuracy
                    && (a.cost < b.cost || a.accuracy > b.accuracy)
            })
        };
        assert!(!front.is_empty());
        for (i, q) in pts.iter().enumerate() {
            if !q.cost.is_finite() {
                assert!(!front.contains(&i), "a NaN point is never on the front");
            } else if front.contains(&i) {
                assert!(!dominated(q), "front point {q:?} is dominated");
            } else {
                assert!(dominated(q), "{q:?} is off the front but not dominated");
            }
        }
        // Sorted by cost, and along the front accuracy strictly rises with cost (or ties repeat).
        for w in front.windows(2) {
            let (a, b) = (&pts[w[0]], &pts[w[1]]);
            assert!(a.cost <= b.cost && (a.cost == b.cost || a.accuracy < b.accuracy), "{a:?} then {b:?}");
        }
    }

    #[test]
    fn pareto_front_by_hand() {
        // (1, 10) and (5, 20) are optimal; (2, 9) and (6, 20) are dominated; (3, 15) is optimal.
        let pts = [p(5.0, 20.0), p(2.0, 9.0), p(1.0, 10.0), p(6.0, 20.0), p(3.0, 15.0)];
        assert_eq!(pareto_front(&pts), vec![2, 4, 0]);
    }

    #[test]
    fn magma_ends_are_the_reference_colours() {
        assert_eq!(magma(0.0), flip_rs::MAGMA[0].map(|c| (c * 255.0).round() as u8));
        assert_eq!(magma(1.0), flip_rs::MAGMA[255].map(|c| (c * 255.0).round() as u8));
        assert_eq!(magma(f32::NAN), magma(1.0));
        // Magma brightens monotonically in its green channel past the first entries.
        assert!(magma(0.9)[1] > magma(0.5)[1]);
    }

    /// A plot decodes as a PNG of the promised size and is not blank.
    #[test]
    fn pareto_plot_writes_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        pareto_plot(&path, "t", "cost", "PSNR", &[p(1.0, 20.0), p(30.0, 25.0), p(100.0, 22.0)]).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (900, 600));
        assert!(img.pixels().any(|px| px.0 != [255, 255, 255]));
    }
}
