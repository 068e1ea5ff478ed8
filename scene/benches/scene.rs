//! Scene benchmarks: BVH rays per second (obvhs, the chosen crate, and with `--features compare-bvh`
//! the `bvh` crate on the same rays), and the time to render one 256x256 view under 30 lights with and
//! without the shadow pass.
//!
//! `cargo bench -p nbrdf-scene --bench scene` (add `--features compare-bvh` for the comparison). Criterion reports
//! throughput in elements/s: rays/s for the `ray_cast` group.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nbrdf::builtin::Builtin;
use nbrdf_scene::scene::builtin::BuiltinMesh;
use nbrdf_scene::scene::render::{render_view, RenderOptions, ShadowPass};
use nbrdf_scene::scene::{Camera, DirectionalLight, Geometry, Mesh, Ray};
use nbrdf::Vec3;
use std::hint::black_box;

/// Deterministic rays from a sphere of radius 3 toward random points of the unit ball (most hit).
fn rays(n: usize) -> Vec<Ray> {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    let mut u = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut dir = move || loop {
        let v = Vec3::new(2.0 * u() - 1.0, 2.0 * u() - 1.0, 2.0 * u() - 1.0);
        if v.length_squared() <= 1.0 && v.length_squared() > 1e-6 {
            return v;
        }
    };
    (0..n)
        .map(|_| {
            let o = dir().normalize() * 3.0;
            let target = dir() * 0.8;
            Ray::new(o, (target - o).normalize())
        })
        .collect()
}

fn meshes() -> Vec<(String, Mesh)> {
    let mut v: Vec<(String, Mesh)> = BuiltinMesh::ALL.iter().map(|m| (m.id().to_string(), m.mesh())).collect();
    let data = std::path::PathBuf::from(std::env::var("NBRDF_DATA").unwrap_or_else(|_| "../shared/data".into()));
    let bunny = data.join("meshes/stanford-bunny.obj");
    match Mesh::load(&bunny) {
        Ok(m) => v.push(("stanford-bunny".into(), m.normalized().0)),
        Err(e) => eprintln!("skipping the bunny: {e}"),
    }
    v
}

#[cfg(feature = "compare-bvh")]
mod alt {
    //! The `bvh` crate (binary SAH BVH) over the same triangles, closest hit by candidate iteration.
    use super::*;
    use nbrdf_scene::scene::ray::intersect_triangle;
    use bvh::aabb::{Aabb, Bounded};
    use bvh::bounding_hierarchy::BHShape;
    use nalgebra::{Point3, Vector3};

    pub struct Tri {
        pub p: [Vec3; 3],
        node: usize,
    }
    impl Bounded<f32, 3> for Tri {
        fn aabb(&self) -> Aabb<f32, 3> {
            let lo = self.p[0].min(self.p[1]).min(self.p[2]);
            let hi = self.p[0].max(self.p[1]).max(self.p[2]);
            Aabb::with_bounds(Point3::new(lo.x, lo.y, lo.z), Point3::new(hi.x, hi.y, hi.z))
        }
    }
    impl BHShape<f32, 3> for Tri {
        fn set_bh_node_index(&mut self, i: usize) {
            self.node = i;
        }
        fn bh_node_index(&self) -> usize {
            self.node
        }
    }

    pub fn build(mesh: &Mesh) -> (bvh::bvh::Bvh<f32, 3>, Vec<Tri>) {
        let mut tris: Vec<Tri> =
            (0..mesh.triangles.len() as u32).map(|t| Tri { p: mesh.corners(t), node: 0 }).collect();
        let b = bvh::bvh::Bvh::build(&mut tris);
        (b, tris)
    }

    pub fn closest(b: &bvh::bvh::Bvh<f32, 3>, tris: &[Tri], r: &Ray) -> Option<f32> {
        let ray = bvh::ray::Ray::new(Point3::new(r.origin.x, r.origin.y, r.origin.z), Vector3::new(r.dir.x, r.dir.y, r.dir.z));
        b.traverse_iterator(&ray, tris)
            .filter_map(|t| intersect_triangle(r.origin, r.dir, 0.0, f32::INFINITY, t.p).map(|h| h.0))
            .min_by(f32::total_cmp)
    }
}

fn ray_cast(c: &mut Criterion) {
    let rays = rays(1 << 16);
    let mut g = c.benchmark_group("ray_cast");
    g.sample_size(10).throughput(Throughput::Elements(rays.len() as u64));
    for (name, mesh) in meshes() {
        let geometry = Geometry::new(mesh).unwrap();
        g.bench_with_input(BenchmarkId::new("obvhs-closest", &name), &rays, |b, rays| {
            b.iter(|| rays.iter().filter(|r| geometry.accel.intersect(r).is_some()).count())
        });
        g.bench_with_input(BenchmarkId::new("obvhs-any", &name), &rays, |b, rays| {
            b.iter(|| rays.iter().filter(|r| geometry.accel.occluded(r)).count())
        });
        #[cfg(feature = "compare-bvh")]
        {
            let (b2, tris) = alt::build(&geometry.mesh);
            // Same answers on the same rays, then the timing.
            for r in rays.iter().take(2000) {
                let a = geometry.accel.intersect(r).map(|h| h.t);
                assert_eq!(a, alt::closest(&b2, &tris, r), "the two BVHs disagree");
            }
            g.bench_with_input(BenchmarkId::new("bvh-crate-closest", &name), &rays, |b, rays| {
                b.iter(|| rays.iter().filter(|r| alt::closest(&b2, &tris, r).is_some()).count())
            });
        }
    }
    g.finish();
}

fn lights(n: usize, toward: Vec3) -> Vec<DirectionalLight> {
    let f = nbrdf_scene::scene::Frame::from_normal(toward.normalize());
    (0..n)
        .map(|i| {
            let z = 1.0 - (i as f32 + 0.5) / n as f32;
            let phi = 2.399_963 * i as f32;
            let r = (1.0 - z * z).sqrt();
            DirectionalLight::new(f.to_world(Vec3::new(r * phi.cos(), r * phi.sin(), z)), [1.0; 3]).unwrap()
        })
        .collect()
}

fn render(c: &mut Criterion) {
    let eye = Vec3::new(1.5, -2.0, 2.0);
    let cam = Camera::look_at(eye, Vec3::ZERO, Vec3::Z, 0.75, 256, 256).unwrap();
    let lights = lights(30, eye);
    let material = |_: &nbrdf_scene::scene::SurfaceSample, wi, wo| Builtin::TwoLobeMetal.eval(wi, wo);
    let mut g = c.benchmark_group("render_256x256_30_lights");
    g.sample_size(10);
    for mesh in [BuiltinMesh::Torus, BuiltinMesh::Sphere] {
        let geometry = Geometry::new(mesh.mesh()).unwrap();
        for (label, shadows) in [("shadow-pass", ShadowPass::Force), ("no-shadow-pass", ShadowPass::Off)] {
            let opts = RenderOptions { shadows, ..Default::default() };
            g.bench_function(BenchmarkId::new(label, mesh.id()), |b| {
                b.iter(|| black_box(render_view(&geometry, &cam, &lights, material, &opts)))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, ray_cast, render);
criterion_main!(benches);
