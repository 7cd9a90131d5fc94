//! Triangles traced by Intel Embree 3 (cargo feature `embree`; the library
//! is Debian's `libembree-dev`), in place of [`super::bvh::Bvh`] for the
//! scene's triangles. Spheres and disks keep their exact tests in the
//! project's own tree.
//!
//! Embree's tests run in f32, so they alone would change the geometry by
//! a few 2⁻²⁴ of the coordinates, and a secondary ray, whose origin is
//! offset from its surface by only 2⁻³² (`ray::offset_origin`), would hit
//! the surface it leaves. So every hit Embree proposes goes through an
//! intersection filter: a hit whose plane passes within
//! [`NEAR_PLANE`] · (scene extent + |origin|) of the ray's origin or of its
//! end is decided by the same f64 test the project's tree calls
//! (`TriangleAccel::intersect`, accepting `0 < t < t_max` exactly); the
//! origin of a self-intersection always lies that close to the plane,
//! and other hits are taken as Embree finds them. The closest hit's
//! distance and barycentrics are then the f64 test's for the triangle
//! Embree ranks closest in f32. Where f32 and f64 disagree about which of
//! two triangles meeting at an edge a ray passes through (rays within a
//! few f32 ulps of the edge), the ray can pass between them.
//!
//! Both queries take the same arguments as the tree's, so
//! `Scene::intersect` and `Scene::occluded` read the same either way.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};

use embree3::{
    BufferUsage, Config, Device, Format, Geometry, GeometryKind, HitN, IntersectContext,
    IntersectContextExt, Ray, RayHit, RayN, SoAHit, SoARay, ValidityN,
};
use glam::DVec3;

/// The triangles of a scene in one Embree scene, primitive `i` being the
/// `i`-th triangle given to [`EmbreeTriangles::build`].
pub struct EmbreeTriangles {
    scene: embree3::Scene<'static>,
    /// Bytes Embree holds for this scene (its memory monitor), so that the
    /// scene's memory accounting includes them.
    bytes: Arc<AtomicI64>,
    /// Largest coordinate magnitude of the vertices.
    extent: f64,
}

/// Relative distance from a hit's plane to the ray's origin or end below
/// which the f64 test decides the hit: Embree's f32 distances err by a few
/// 2⁻²⁴ of the coordinates involved, and the origin offset is 2⁻³² of them,
/// so a plane the origin (or end) lies on is always closer than this
/// (2⁻¹⁶, a margin of about 2⁸ over the f32 error).
const NEAR_PLANE: f64 = 1.0 / 65_536.0;

/// The per-query extension of Embree's intersection context.
struct Query<'a> {
    /// The unit direction in f64.
    dir: DVec3,
    t_max: f64,
    /// Hits whose plane passes closer than this to the origin or the end
    /// are decided by `decide` ([`NEAR_PLANE`]).
    near: f64,
    /// The f64 test of a primitive: its distance if it is hit.
    decide: &'a mut dyn FnMut(usize) -> Option<f64>,
}

/// The intersection filter: hits whose plane passes near the ray's origin
/// or end go to the query's f64 test, and those it refuses are dropped.
fn filter(rays: RayN<'_>, hits: HitN<'_>, mut valid: ValidityN<'_>, ctx: &mut IntersectContext) {
    // SAFETY: every query of this module passes an `IntersectContextExt<Query>`,
    // the only context these geometries see.
    let query = unsafe { ctx.ext_mut::<Query<'_>>() };
    for lane in 0..valid.len() {
        if valid[lane] == 0 {
            continue;
        }
        // During a filter call the ray's `tfar` is the proposed hit's distance.
        let t = rays.tfar(lane) as f64;
        let n = glam::Vec3::from(hits.normal(lane)).as_dvec3();
        let slope = query.dir.dot(n).abs() / n.length();
        // A NaN (a degenerate normal) counts as near: the f64 test decides.
        let far = |gap: f64| gap.partial_cmp(&query.near) == Some(std::cmp::Ordering::Greater);
        let near_origin = !far(t * slope);
        let near_end = !far((query.t_max - t) * slope);
        if (near_origin || near_end) && (query.decide)(hits.prim_id(lane) as usize).is_none() {
            valid[lane] = 0;
        }
    }
}

impl EmbreeTriangles {
    /// One Embree scene over `triangles` (world-space vertices). Embree
    /// builds on the calling thread (`threads=1`): scene loads already run
    /// off the async runtime, one per blocking task.
    pub fn build(
        triangles: impl ExactSizeIterator<Item = [DVec3; 3]>,
    ) -> Result<EmbreeTriangles, embree3::Error> {
        let device = Device::with_config(Config {
            threads: 1,
            ..Config::default()
        })?;
        let bytes = Arc::new(AtomicI64::new(0));
        let counter = Arc::clone(&bytes);
        device.set_memory_monitor_function(move |delta, _| {
            counter.fetch_add(delta as i64, Ordering::Relaxed);
            true
        });
        let mut scene = device.create_scene()?;
        let count = triangles.len();
        let mut extent = 0.0f64;
        if count > 0 {
            let mut mesh = device.create_geometry(GeometryKind::TRIANGLE)?;
            // Unindexed: each triangle has its own three vertices, converted
            // from the same f64 values wherever triangles share a vertex, so
            // neighbours still share their edges exactly in f32.
            let mut vertices = mesh.set_new_buffer::<[f32; 3]>(
                BufferUsage::VERTEX,
                0,
                Format::FLOAT3,
                12,
                3 * count,
            )?;
            for (k, p) in triangles.enumerate() {
                for (j, v) in p.iter().enumerate() {
                    extent = extent.max(v.abs().max_element());
                    vertices[3 * k + j] = v.as_vec3().to_array();
                }
            }
            let mut indices =
                mesh.set_new_buffer::<[u32; 3]>(BufferUsage::INDEX, 0, Format::UINT3, 12, count)?;
            for (k, index) in indices.iter_mut().enumerate() {
                let first = 3 * k as u32;
                *index = [first, first + 1, first + 2];
            }
            mesh.set_intersect_filter_function::<_, ()>(|r, h, v, c, _| filter(r, h, v, c));
            mesh.set_occluded_filter_function::<_, ()>(|r, h, v, c, _| filter(r, h, v, c));
            let mesh: Geometry<'static> = mesh.commit();
            scene.attach_geometry(&mesh);
        }
        scene.commit();
        Ok(EmbreeTriangles {
            scene,
            bytes,
            extent,
        })
    }

    /// Bytes Embree holds for the scene.
    pub fn heap_bytes(&self) -> u64 {
        self.bytes.load(Ordering::Relaxed).max(0) as u64
    }

    /// Closest hit, as `Bvh::closest`: `intersect(i, t_max)` is the f64 test
    /// of primitive `i` (module docs say when the filter calls it); the
    /// triangle Embree finds closest is tested once more and its f64
    /// distance returned. Should that test refuse it (f32 and f64 disagree
    /// at an edge), the search goes on beyond it. `_prims` is not needed.
    #[inline]
    pub fn closest<P>(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_max: f64,
        _prims: &[P],
        mut intersect: impl FnMut(usize, f64) -> Option<f64>,
    ) -> Option<f64> {
        let mut decide = |i: usize| intersect(i, t_max);
        let mut ctx = self.context(origin, dir, t_max, &mut decide);
        let mut t_near = 0.0f32;
        for _ in 0..MAX_SEARCHES {
            let mut rayhit = RayHit::from_ray(f32_ray(origin, dir, t_near, t_max));
            self.scene.intersect(&mut ctx, &mut rayhit);
            if !rayhit.hit.is_valid() {
                return None;
            }
            if let Some(t) = (ctx.ext.decide)(rayhit.hit.primID as usize) {
                return Some(t);
            }
            t_near = rayhit.ray.tfar.next_up();
        }
        None
    }

    /// Any hit, as `Bvh::any`: true once Embree finds a hit the filter keeps.
    #[inline]
    pub fn any<P>(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_max: f64,
        _prims: &[P],
        mut intersect: impl FnMut(usize, f64) -> bool,
    ) -> bool {
        let mut decide = |i: usize| intersect(i, t_max).then_some(t_max);
        let mut ctx = self.context(origin, dir, t_max, &mut decide);
        self.scene
            .occluded(&mut ctx, &mut f32_ray(origin, dir, 0.0, t_max))
    }

    /// The intersection context of one query.
    fn context<'a>(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_max: f64,
        decide: &'a mut dyn FnMut(usize) -> Option<f64>,
    ) -> IntersectContextExt<Query<'a>> {
        IntersectContextExt::incoherent(Query {
            dir,
            t_max,
            near: NEAR_PLANE * (self.extent + origin.abs().max_element()),
            decide,
        })
    }
}

/// Searches past triangles the f64 test refuses before a ray counts as a
/// miss; each refusal is a ray within a few f32 ulps of an edge, so more
/// than one in a row does not happen on real geometry.
const MAX_SEARCHES: usize = 4;

/// The ray for Embree: origin and direction rounded to f32, and `tfar`
/// rounded up, so that no hit the f64 test would accept lies beyond the
/// segment for want of an ulp (the f64 test applies the exact bound).
fn f32_ray(origin: DVec3, dir: DVec3, t_near: f32, t_max: f64) -> Ray {
    let t_far = t_max as f32;
    let t_far = if (t_far as f64) < t_max {
        t_far.next_up()
    } else {
        t_far
    };
    Ray::segment(
        origin.as_vec3().to_array(),
        dir.as_vec3().to_array(),
        t_near,
        t_far,
    )
}
