//! Scene model and ray tracing: loading JSON scenes (`docs/scene-format.md`),
//! shapes, materials, emitters, environment lighting, the camera and the BVH.
//! The plugin families (`material`: BSDFs, `emitter`: lights, `texture`)
//! keep each plugin in a file of its own, registered by one line of their
//! `plugins!` invocation.
//!
//! All geometry is f64 at the API. Everything is immutable after loading, so
//! a [`Scene`] is `Send + Sync` and callers trace rays in parallel (rayon).

pub(crate) mod archive;
mod bilinear;
mod bitmap;
mod budget;
pub(crate) mod bundle;
mod bvh;
mod camera;
mod digest;
pub mod emitter;
mod environment;
mod error;
mod files;
mod format;
pub(crate) mod formats;
#[doc(hidden)]
pub mod generate;
mod loader;
pub mod material;
mod mesh;
pub mod meter;
mod mitsuba;
mod params;
mod pixel_filter;
mod ply;
mod ray;
mod read;
mod serialized;

pub(crate) use loader::read_scene_file;
pub mod shape;
pub mod texture;
mod transform;

use glam::{DVec2, DVec3};

pub use budget::LoadLimits;
pub use camera::Camera;
pub use digest::SceneDigest;
pub use emitter::Emitter;
/// Writes an equirectangular map as a half-float EXR (tests and the bundled
/// scenes' generator make their environment maps with it).
#[doc(hidden)]
pub use environment::write_exr_half;
pub use environment::{Environment, EnvironmentMap};
pub use error::SceneError;
pub use format::FovAxis;
pub use material::Material;
pub use mitsuba::{MAX_WARNINGS, MitsubaOptions, Warning, Warnings};
pub use pixel_filter::PixelFilter;
pub use ray::Ray;

use bvh::Bvh;
use shape::{Geometry, Shape, Triangle, TriangleAccel, TriangleTag};

/// Longest path a scene may ask to be rendered with, in segments: Russian
/// roulette cannot end paths in a closed scene of albedo 1, so the depth
/// bound is what keeps a request finite.
pub const MAX_PATH_DEPTH: u32 = 1024;

/// Largest number of triangles a scene may hold (also bounded by
/// [`MAX_SCENE_MEMORY_BYTES`]; see [`TRIANGLE_BYTES`]).
pub const MAX_TRIANGLES: usize = 10_000_000;
/// Most bytes a scene's geometry may take once built, estimated from its
/// triangle count before building ([`TRIANGLE_BYTES`] each). 1 GiB (≈ 3.3
/// million triangles) keeps one scene well inside a few-GiB service, which
/// also caps all scenes together (`scenes.max_scene_bytes`). Measured: about
/// 226 bytes per triangle without vertex normals.
pub const MAX_SCENE_MEMORY_BYTES: u64 = 1 << 30;
/// Upper bound of the bytes one triangle retains in a built scene: the
/// world-space triangle, its intersection form and hit tag, its
/// entry in its shape's area CDF, vertex normals and texture coordinates
/// (if it has them) and at
/// two thirds of a BVH node (the 4-wide tree over N primitives has fewer
/// than 2N/3 nodes, `bvh::Bvh::build`).
pub const TRIANGLE_BYTES: u64 = (std::mem::size_of::<Triangle>()
    + std::mem::size_of::<TriangleAccel>()
    + std::mem::size_of::<TriangleTag>()
    + std::mem::size_of::<f64>()
    + std::mem::size_of::<[DVec3; 3]>()
    + std::mem::size_of::<[DVec2; 3]>()
    + (2 * bvh::NODE_BYTES).div_ceil(3)) as u64;

/// Estimated bytes retained by `triangles` triangles ([`TRIANGLE_BYTES`]).
pub fn triangle_bytes(triangles: usize) -> u64 {
    (triangles as u64).saturating_mul(TRIANGLE_BYTES)
}
/// Largest number of shapes in one scene file.
pub const MAX_SHAPES: usize = 100_000;

/// A ray's closest intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Distance along the ray.
    pub t: f64,
    /// Hit point, projected onto the surface.
    pub position: DVec3,
    /// Unit geometric normal of the front side as authored; NOT flipped
    /// towards the ray (compare with the ray direction to tell the side).
    pub normal: DVec3,
    /// Unit shading normal: interpolated vertex normals where a mesh has
    /// them (on the front side), otherwise equal to `normal`.
    pub shading_normal: DVec3,
    /// Texture coordinates (Mitsuba 3's per shape: interpolated vertex
    /// `uvs` on meshes that have them, the barycentrics `(b1, b2)` on
    /// those that do not; see `docs/scene-format.md`).
    pub uv: DVec2,
    /// ∂p/∂u, world units per unit of `u` (not necessarily orthogonal to
    /// the shading normal): the tangent of the shading frame of
    /// anisotropic and normal-mapped BSDFs, as in Mitsuba 3
    /// ([`SurfaceHit::shading_frame`]), and with [`Self::dp_dv`] what a
    /// bump map tilts. Zero where `u` does not vary.
    pub dp_du: DVec3,
    /// ∂p/∂v, world units per unit of `v`.
    pub dp_dv: DVec3,
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// Index into [`Scene::emitters`] if the shape is an area light.
    pub emitter: Option<usize>,
    /// Index of the shape in the scene file's `shapes` list.
    pub shape: usize,
    /// Triangle index within the shape (0 for spheres and disks).
    pub primitive: u32,
}

impl SurfaceHit {
    /// The shading frame of an anisotropic or normal-mapped BSDF: the
    /// shading normal, and `dp_du` made orthogonal to it as the first
    /// tangent and `n × s` the bitangent (Mitsuba 3.9's `sh_frame`, even
    /// where the texture coordinates are mirrored); where `dp_du` is zero
    /// or along the normal, the frame [`Frame::from_normal`] builds.
    pub fn shading_frame(&self) -> crate::sphere::Frame {
        let n = self.shading_normal;
        match (self.dp_du - n * n.dot(self.dp_du)).try_normalize() {
            Some(s) => crate::sphere::Frame {
                s,
                t: n.cross(s),
                n,
            },
            None => crate::sphere::Frame::from_normal(n),
        }
    }
}

/// A loaded scene. Immutable; `Send + Sync`.
pub struct Scene {
    pub name: String,
    /// Content address of the document and its files (see [`SceneDigest`]);
    /// the same for the same scene in any process.
    pub digest: SceneDigest,
    /// The files the scene was built from besides its document (meshes,
    /// maps, textures), relative to the scenes root it was loaded under,
    /// in the order they were read.
    pub files: Vec<std::path::PathBuf>,
    pub materials: Vec<Material>,
    /// Material ids from the scene file, parallel to `materials`.
    pub material_ids: Vec<String>,
    pub emitters: Vec<Emitter>,
    /// The irradiance meters on the scene's shapes, in document order.
    pub meters: Vec<meter::IrradianceMeter>,
    pub environment: Option<Environment>,
    pub camera: Camera,
    /// Camera rays pass through area emitters and see no environment
    /// (Mitsuba 3's `hide_emitters`); light still comes from them.
    pub hide_emitters: bool,
    /// The depth requests on the scene default to, in segments from the
    /// camera (Mitsuba's integrator `max_depth`), in
    /// `1..=`[`MAX_PATH_DEPTH`]; `None`: the service's.
    pub max_depth: Option<u32>,
    /// Whether a material makes caustics ([`Material::makes_caustics`]),
    /// probed once at load: the presets path trace such scenes.
    caustic_surfaces: bool,
    shapes: Vec<Shape>,
    /// World-space triangles in authoring order (shape by shape).
    triangles: Vec<Triangle>,
    /// Per-vertex shading normals of triangles that have them.
    vertex_normals: Vec<[DVec3; 3]>,
    /// Per-vertex texture coordinates of triangles that have them.
    vertex_uvs: Vec<[DVec2; 3]>,
    /// Triangles in BVH order, and what a hit on each reports.
    accel: Vec<TriangleAccel>,
    accel_tags: Vec<TriangleTag>,
    triangle_bvh: Bvh,
    /// Spheres and disks: their own small BVH over shape indices.
    analytic_bvh: Bvh,
    analytic_shapes: Vec<u32>,
    bounds: bvh::Aabb,
}

impl Scene {
    /// Whether a material of the scene makes caustics
    /// ([`Material::makes_caustics`]), as probed at load.
    pub fn has_caustic_surfaces(&self) -> bool {
        self.caustic_surfaces
    }

    /// Loads a scene file: Mitsuba 3 XML if the extension is `.xml` (strict:
    /// unsupported features are errors), JSON otherwise. Referenced files
    /// must lie inside `scenes_root`.
    pub fn load(
        path: &std::path::Path,
        scenes_root: &std::path::Path,
    ) -> Result<Scene, SceneError> {
        let options = MitsubaOptions::default();
        formats::load(path, scenes_root, &options, &LoadLimits::default()).map(|(scene, _)| scene)
    }

    /// Loads a scene file by its extension (`.xml`: Mitsuba 3 XML read with
    /// `options`; anything else: the JSON document) within `limits`: what
    /// it may hold while loading and the flag that stops it. Returns what
    /// was approximated.
    pub fn load_within(
        path: &std::path::Path,
        scenes_root: &std::path::Path,
        options: &MitsubaOptions,
        limits: &LoadLimits,
    ) -> Result<(Scene, Warnings), SceneError> {
        formats::load(path, scenes_root, options, limits)
    }

    /// Parses a scene from text; relative file names resolve against
    /// `base_dir`, and every referenced file must lie inside `scenes_root`.
    pub fn from_json_str(
        text: &str,
        base_dir: &std::path::Path,
        scenes_root: &std::path::Path,
    ) -> Result<Scene, SceneError> {
        loader::from_json_str(
            text,
            "<string>",
            base_dir,
            scenes_root,
            &LoadLimits::default(),
        )
    }

    /// Parses a Mitsuba 3 XML scene from text (see `docs/scene-format.md`,
    /// "Mitsuba 3 XML"); relative file names resolve against `base_dir` and
    /// must lie inside `scenes_root`. Returns the approximations made.
    pub fn from_mitsuba_xml_str(
        text: &str,
        base_dir: &std::path::Path,
        scenes_root: &std::path::Path,
        options: &MitsubaOptions,
    ) -> Result<(Scene, Warnings), SceneError> {
        let limits = LoadLimits::default();
        mitsuba::from_str(text, "<string>", base_dir, scenes_root, options, &limits)
    }

    /// Loads a Mitsuba 3 XML scene file with `options`; see
    /// [`Scene::from_mitsuba_xml_str`].
    pub fn load_mitsuba_xml(
        path: &std::path::Path,
        scenes_root: &std::path::Path,
        options: &MitsubaOptions,
    ) -> Result<(Scene, Warnings), SceneError> {
        mitsuba::load(path, scenes_root, options, &LoadLimits::default())
    }

    /// Closest hit with `0 < t < ray.t_max`.
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        let (o, d) = (ray.origin, ray.dir);
        let mut tri_hit = None;
        let t_tri = self.triangle_bvh.closest(
            o,
            d,
            ray.t_max,
            &self.accel,
            #[inline(always)]
            |i, t_max| {
                let (t, u, v) = self.accel[i].intersect(o, d, t_max)?;
                // The tag is read here, not after the traversal, so that its
                // cache miss overlaps the rest of the traversal.
                tri_hit = Some((i, u, v, self.accel_tags[i]));
                Some(t)
            },
        );
        let mut analytic_hit = 0usize;
        let t_analytic = self.analytic_bvh.closest(
            o,
            d,
            t_tri.unwrap_or(ray.t_max),
            &self.analytic_shapes,
            |i, t_max| {
                let shape = self.analytic_shapes[i] as usize;
                let t = self.shapes[shape].intersect_analytic(o, d, t_max)?;
                analytic_hit = shape;
                Some(t)
            },
        );
        if let Some(t) = t_analytic {
            let shape = &self.shapes[analytic_hit];
            let (position, normal, uv, [dp_du, dp_dv]) = shape.analytic_hit(o, d, t);
            return Some(SurfaceHit {
                t,
                position,
                normal,
                shading_normal: normal,
                uv,
                dp_du,
                dp_dv,
                material: shape.material,
                emitter: shape.emitter,
                shape: analytic_hit,
                primitive: 0,
            });
        }
        let t = t_tri?;
        let (i, u, v, tag) = tri_hit?;
        let tri = &self.accel[i];
        let shape = &self.shapes[tag.shape as usize];
        let normal = tri.normal();
        let shading_normal = match self.vertex_normals.get(tag.normals as usize) {
            Some(n) => (n[0] * (1.0 - u - v) + n[1] * u + n[2] * v)
                .try_normalize()
                .unwrap_or(normal),
            None => normal,
        };
        // ∂p/∂u and ∂p/∂v from the texture coordinates' parametrisation
        // (the barycentric one where the mesh has none: e1 and e2).
        let (uv, [dp_du, dp_dv]) = match self.vertex_uvs.get(tag.uvs as usize) {
            Some(t) => {
                let (d1, d2) = (t[1] - t[0], t[2] - t[0]);
                let det = d1.x * d2.y - d1.y * d2.x;
                let dp = if det.abs() > 1e-20 {
                    [
                        (tri.e1 * d2.y - tri.e2 * d1.y) / det,
                        (tri.e2 * d1.x - tri.e1 * d2.x) / det,
                    ]
                } else {
                    [DVec3::ZERO; 2]
                };
                (t[0] * (1.0 - u - v) + t[1] * u + t[2] * v, dp)
            }
            None => (DVec2::new(u, v), [tri.e1, tri.e2]),
        };
        Some(SurfaceHit {
            t,
            position: tri.point(u, v),
            normal,
            shading_normal,
            uv,
            dp_du,
            dp_dv,
            material: shape.material,
            emitter: shape.emitter,
            shape: tag.shape as usize,
            primitive: tag.primitive,
        })
    }

    /// True if anything is hit with `0 < t < ray.t_max` (stops at the first).
    pub fn occluded(&self, ray: &Ray) -> bool {
        let (o, d) = (ray.origin, ray.dir);
        self.triangle_bvh.any(
            o,
            d,
            ray.t_max,
            &self.accel,
            #[inline(always)]
            |i, t_max| self.accel[i].intersect(o, d, t_max).is_some(),
        ) || self
            .analytic_bvh
            .any(o, d, ray.t_max, &self.analytic_shapes, |i, t_max| {
                self.shapes[self.analytic_shapes[i] as usize]
                    .intersect_analytic(o, d, t_max)
                    .is_some()
            })
    }

    /// Ray leaving the surface point `position` (geometric normal `normal`,
    /// either orientation) along the unit direction `dir`; the origin is
    /// offset to the side `dir` points to, by a margin that grows with the
    /// coordinates' magnitude (`ray::offset_origin`).
    pub fn spawn_ray(&self, position: DVec3, normal: DVec3, dir: DVec3) -> Ray {
        Ray {
            origin: ray::offset_origin(position, normal, dir),
            dir,
            t_max: f64::INFINITY,
        }
    }

    /// Shadow ray from a surface point towards `target`. When `target` lies
    /// on a surface, pass its geometric normal so the end is offset too and
    /// the target's own surface never counts as an occluder; otherwise the
    /// ray stops just short of `target`. A zero-length connection gives a ray
    /// with `t_max = 0`, which nothing occludes.
    pub fn spawn_ray_to(
        &self,
        position: DVec3,
        normal: DVec3,
        target: DVec3,
        target_normal: Option<DVec3>,
    ) -> Ray {
        let origin = ray::offset_origin(position, normal, target - position);
        let (end, shorten) = match target_normal {
            Some(n) => (ray::offset_origin(target, n, position - target), 1.0),
            None => (target, 1.0 - 1e-9),
        };
        let d = end - origin;
        let dist = d.length();
        if dist.is_nan() || dist <= 0.0 {
            return Ray {
                origin,
                dir: normal,
                t_max: 0.0,
            };
        }
        Ray {
            origin,
            dir: d / dist,
            t_max: dist * shorten,
        }
    }

    /// Uniform point on shape `shape` by area for `u ∈ [0, 1)²`: (point,
    /// front normal, pdf = 1 / area per unit area).
    pub fn sample_shape_area(&self, shape: usize, u: [f64; 2]) -> (DVec3, DVec3, f64) {
        let (p, n, pdf, _) = self.sample_shape_area_uv(shape, u);
        (p, n, pdf)
    }

    /// [`Self::sample_shape_area`] with the texture coordinates of the
    /// point (as a hit there reports them, `SurfaceHit::uv`).
    pub fn sample_shape_area_uv(&self, shape: usize, u: [f64; 2]) -> (DVec3, DVec3, f64, DVec2) {
        let s = &self.shapes[shape];
        let pdf = 1.0 / s.area;
        match &s.geometry {
            Geometry::Mesh { first, count, cdf } => {
                let k = cdf.partition_point(|&c| c <= u[0]).min(count - 1);
                let lo = if k == 0 { 0.0 } else { cdf[k - 1] };
                let u0 = ((u[0] - lo) / (cdf[k] - lo)).clamp(0.0, 1.0);
                let tri = &self.triangles[first + k];
                let (b1, b2) = shape::sample_barycentric([u0, u[1]]);
                let uv = match self.vertex_uvs.get(tri.uvs as usize) {
                    Some(t) => t[0] * (1.0 - b1 - b2) + t[1] * b1 + t[2] * b2,
                    None => DVec2::new(b1, b2),
                };
                (tri.point(b1, b2), tri.normal(), pdf, uv)
            }
            _ => {
                let (p, n) = s.sample_analytic(u);
                // The hit's parametrisation at the point itself (t = 0).
                let (_, _, uv, _) = s.analytic_hit(p, DVec3::Z, 0.0);
                (p, n, pdf, uv)
            }
        }
    }

    /// Surface area of shape `shape`, world units².
    pub fn shape_area(&self, shape: usize) -> f64 {
        self.shapes[shape].area
    }

    /// Axis-aligned bounds of shape `shape`, (min, max).
    pub fn shape_bounds(&self, shape: usize) -> (DVec3, DVec3) {
        let s = &self.shapes[shape];
        let b = match &s.geometry {
            Geometry::Mesh { first, count, .. } => self.triangles[*first..first + count]
                .iter()
                .fold(bvh::Aabb::EMPTY, |b, t| b.union(t.bounds())),
            _ => s.analytic_bounds(),
        };
        (b.min, b.max)
    }

    /// Number of shapes (entries of the scene file's `shapes`).
    pub fn shape_count(&self) -> usize {
        self.shapes.len()
    }

    /// Material index of shape `shape`.
    pub fn shape_material(&self, shape: usize) -> usize {
        self.shapes[shape].material
    }

    /// Emitter index of shape `shape`, if it is an area light.
    pub fn shape_emitter(&self, shape: usize) -> Option<usize> {
        self.shapes[shape].emitter
    }

    /// Axis-aligned bounds of all geometry, (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.bounds.min, self.bounds.max)
    }

    /// World-space vertices of every triangle, in authoring order (to feed
    /// another ray tracer the same geometry, e.g. for a benchmark).
    pub fn triangle_vertices(&self) -> impl Iterator<Item = [DVec3; 3]> + '_ {
        self.triangles.iter().map(|t| t.p)
    }

    /// Number of triangles (spheres and disks are analytic and not counted).
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Bytes the scene holds on the heap (geometry, acceleration structures,
    /// every image: textures of materials and emitters, the environment
    /// map), counted from its allocations; small per-material and
    /// per-emitter data are left out.
    pub fn heap_bytes(&self) -> u64 {
        fn bytes<T>(v: &Vec<T>) -> u64 {
            (v.capacity() * std::mem::size_of::<T>()) as u64
        }
        let cdfs: u64 = self
            .shapes
            .iter()
            .map(|s| match &s.geometry {
                Geometry::Mesh { cdf, .. } => bytes(cdf),
                _ => 0,
            })
            .sum();
        // Each image once, however many textures (materials' and area
        // emitters') share it.
        let mut seen = std::collections::HashSet::new();
        let emitted = self.emitters.iter().filter_map(|e| match e {
            Emitter::Area(area) => Some(&area.radiance),
            _ => None,
        });
        let textures: u64 = self
            .materials
            .iter()
            .flat_map(Material::textures)
            .chain(emitted)
            .filter_map(|t| match t {
                texture::Texture::Bitmap(b) => Some(b),
                _ => None,
            })
            .filter(|b| seen.insert(std::sync::Arc::as_ptr(&b.bitmap)))
            .map(|b| b.bitmap.heap_bytes())
            .sum();
        let environment = match &self.environment {
            Some(Environment::Map(map)) => map.heap_bytes(),
            _ => 0,
        };
        bytes(&self.shapes)
            + cdfs
            + bytes(&self.triangles)
            + bytes(&self.vertex_normals)
            + bytes(&self.vertex_uvs)
            + textures
            + bytes(&self.accel)
            + bytes(&self.accel_tags)
            + bytes(&self.analytic_shapes)
            + self.triangle_bvh.heap_bytes()
            + self.analytic_bvh.heap_bytes()
            + environment
    }
}

#[cfg(test)]
mod tests;
