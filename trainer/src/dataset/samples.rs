//! Training samples: the lit, unshadowed pixels of a data set, in the local shading frame.
//!
//! Each pixel ray of a view is cast once; for every image the hit gets the light's visibility `I_s`
//! (Eq. 9, the renderer's own [`visibility`]) and the pair `(l, v)` goes into the frame of
//! [`Frame::from_normal`](nbrdf_scene::scene::Frame::from_normal) of the interpolated normal, here and
//! nowhere else (DESIGN.md, "How data flows", step 2).

use nbrdf_scene::scene::render::{visibility, GBuffer, Visibility};
use nbrdf::{Error, Rgb};
use rayon::prelude::*;

use super::{err, Dataset, Split};

/// Samples as a structure of arrays; index `i` of every array is one pixel of one image.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    /// View index in the data set.
    pub view: Vec<u32>,
    /// Image index within the view.
    pub image: Vec<u32>,
    /// Pixel index `row * width + col`.
    pub pixel: Vec<u32>,
    /// Hit triangle (the `x` of the models, with the barycentrics).
    pub triangle: Vec<u32>,
    /// Barycentrics `(b1, b2)` of the triangle's second and third corners.
    pub barycentric: Vec<[f32; 2]>,
    /// World position of the hit (normalised mesh coordinates for semi-synthetic data).
    pub position: Vec<[f32; 3]>,
    /// Interpolated unit shading normal, world coordinates (local `+z`).
    pub normal: Vec<[f32; 3]>,
    /// Direction toward the light `l`, local frame (`wi`; `wi.z = cos θ_l > 0`).
    pub wi: Vec<[f32; 3]>,
    /// Direction toward the camera `v`, local frame (`wo`, `wo.z > 0`).
    pub wo: Vec<[f32; 3]>,
    /// Light intensity `L_i`.
    pub intensity: Vec<Rgb>,
    /// Observed radiance `L_o`.
    pub radiance: Vec<Rgb>,
    /// Per view of the split: how many masked pixels (of the stride) its rays hit the mesh for.
    pub coverage: Vec<Coverage>,
}

/// How well a view's mask and its camera's view of the mesh agree: masked pixels whose ray misses the
/// mesh are a sign of wrong intrinsics, a camera facing away or another mesh.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Coverage {
    /// View index in the data set.
    pub view: u32,
    /// Masked pixels (of the stride).
    pub masked: usize,
    /// Of those, the pixels whose ray misses the mesh.
    pub missed: usize,
}

impl Samples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.triangle.len()
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.triangle.is_empty()
    }

    fn append(&mut self, mut o: Samples) {
        self.view.append(&mut o.view);
        self.image.append(&mut o.image);
        self.pixel.append(&mut o.pixel);
        self.triangle.append(&mut o.triangle);
        self.barycentric.append(&mut o.barycentric);
        self.position.append(&mut o.position);
        self.normal.append(&mut o.normal);
        self.wi.append(&mut o.wi);
        self.wo.append(&mut o.wo);
        self.intensity.append(&mut o.intensity);
        self.radiance.append(&mut o.radiance);
        self.coverage.append(&mut o.coverage);
    }
}

/// The samples of every view of `split`: masked pixels whose ray hits the mesh, with the light above
/// the shading horizon, unshadowed (shadow rays unless the mesh is convex), and seen from above the
/// horizon. Radiance is kept as read, NaN and infinity included (the consumer decides, and counts, what
/// it drops). `pixel_stride` keeps every n-th pixel (by pixel index). Order: views, then images, then
/// pixels, independent of threading.
pub fn samples(ds: &Dataset, split: Split, pixel_stride: usize) -> crate::Result<Samples> {
    let stride = pixel_stride.max(1);
    let geometry = &ds.geometry;
    let mut out = Samples::default();
    for (vi, view) in ds.views.iter().enumerate().filter(|(_, v)| v.split == split) {
        let cam = &view.camera;
        let n = cam.width as usize * cam.height as usize;
        if view.mask.len() != n {
            return Err(crate::Error::from(Error::SizeMismatch { what: "view mask pixel count", expected: n, found: view.mask.len() }));
        }
        let gbuffer = GBuffer::cast(geometry, cam);
        let masked: Vec<usize> = (0..n).step_by(stride).filter(|&p| view.mask[p]).collect();
        let missed = masked.iter().filter(|&&p| gbuffer.samples[p].is_none()).count();
        out.coverage.push(Coverage { view: vi as u32, masked: masked.len(), missed });
        let per_image: Vec<crate::Result<Samples>> = view
            .images
            .par_iter()
            .enumerate()
            .map(|(ii, im)| {
                let img = im.load()?;
                if (img.width, img.height) != (cam.width, cam.height) {
                    return Err(crate::Error::from(err(
                        "data set image",
                        format!(
                            "view {vi} image {ii} ({}): {}x{} pixels, the camera has {}x{}",
                            im.path().display(),
                            img.width,
                            img.height,
                            cam.width,
                            cam.height
                        ),
                    )));
                }
                let mut s = Samples::default();
                let l = im.light.direction;
                for p in (0..n).step_by(stride) {
                    let (true, Some(g)) = (view.mask[p], gbuffer.samples[p].as_ref()) else { continue };
                    if !matches!(visibility(geometry, g, l, !geometry.convex), Visibility::Lit { .. }) {
                        continue;
                    }
                    let frame = g.frame();
                    let (wi, wo) = (frame.to_local(l), frame.to_local(g.view));
                    // A NaN or infinite pixel stays: the trainer's sanitizing drops it and counts it.
                    let radiance = img.data[p];
                    if wo.z <= 0.0 {
                        continue;
                    }
                    s.view.push(vi as u32);
                    s.image.push(ii as u32);
                    s.pixel.push(p as u32);
                    s.triangle.push(g.hit.triangle);
                    s.barycentric.push([g.hit.b1, g.hit.b2]);
                    s.position.push(g.position.to_array());
                    s.normal.push(g.normal.to_array());
                    s.wi.push(wi.to_array());
                    s.wo.push(wo.to_array());
                    s.intensity.push(im.light.intensity);
                    s.radiance.push(radiance);
                }
                Ok(s)
            })
            .collect();
        for s in per_image {
            out.append(s?);
        }
    }
    Ok(out)
}
