//! Placed shapes: triangle meshes (rectangles, cubes, mesh files and inline
//! lists all become triangles, exactly) and the analytic sphere and disk;
//! and the shape family, the plugins a document's `shapes` name by `type`.
//!
//! Spheres are intersected analytically (no tessellation error); their
//! `to_world` must therefore be a similarity (rotation, uniform scale,
//! translation). Disks accept any affine `to_world` (an ellipse stays planar
//! and its area scales by a constant, so area sampling stays uniform).
//!
//! Each shape plugin has its own file below holding its parameters' docs,
//! their reading and validation ([`ShapeFields`]) and its geometry: a local
//! mesh, or an analytic [`Surface`] with its intersection, hit details and
//! sampling ([`Plugin`]); the `plugins!` invocation below is the registry
//! of the `shapes` plugins. The generic fields (`type`, `id`, `material`,
//! `to_world`, `emitter`, `flip_normals`) are the family's, handled once by
//! the loader.

use std::f64::consts::PI;

use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;

use glam::{DAffine3, DVec2, DVec3};
use serde::de::{self, Deserializer, EnumAccess, Unexpected, VariantAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use super::budget::Budget;
use super::bvh::Aabb;
use super::error::SceneError;
use super::format::ShapeKind;
use super::mesh::MeshData;

mod fields;
pub(crate) use fields::ShapeFields;

/// A shape plugin: what the loader needs of one `type` of shape. Each
/// plugin's file implements it on its (unit) type.
pub(crate) trait Plugin {
    /// The parameters the plugin takes; a document giving any other is
    /// refused, naming that field.
    const FIELDS: &'static [&'static str] = &[];
    /// The reader of the mesh file its `filename` names, for plugins whose
    /// mesh is a file: the loader reads every such file once, in parallel,
    /// within the load's budget, before building any shape.
    const MESH_FILE: Option<ReadMesh> = None;
    /// Whether Mitsuba 3 has the plugin under the same name (the Mitsuba
    /// reader maps `<shape type=…>` through this registry).
    const MITSUBA: bool = true;
    /// Triangles of its fixed local mesh, counted before any is built.
    const FIXED_TRIANGLES: usize = 0;

    /// Which mesh of its file to read (plugins with a
    /// [`Plugin::MESH_FILE`]; files of one mesh have only mesh 0).
    fn mesh_index(_: &ShapeFields) -> Result<u32, SceneError> {
        Ok(0)
    }

    /// Triangles the document lists inline, counted before any mesh file
    /// is read (they narrow what the files may hold).
    fn inline_triangles(_: &ShapeFields) -> Result<usize, SceneError> {
        Ok(0)
    }

    /// The shape's geometry from its document: a local mesh for the loader
    /// to place, or analytic geometry in world space.
    fn build<'a>(fields: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError>;
}

/// An analytic surface in world space, as its plugin intersects, describes
/// and samples it. Normals are the surface's own (outward) ones: the shape
/// turns them for `flip_normals`.
pub(crate) trait Surface: std::fmt::Debug + Send + Sync {
    /// World bounds.
    fn bounds(&self) -> Aabb;
    /// Distance along a unit-direction ray, if in (0, t_max).
    fn intersect(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<f64>;
    /// Surface point, normal, texture coordinates and `[∂p/∂u, ∂p/∂v]`
    /// (Mitsuba 3's, lengths included: bump maps scale by them) of a hit
    /// at `t`, the point projected back onto the surface so the error is a
    /// few ulps.
    fn hit(&self, o: DVec3, d: DVec3, t: f64) -> (DVec3, DVec3, DVec2, [DVec3; 2]);
    /// A point uniform by area from `u` in [0,1)², and its normal.
    fn sample(&self, u: [f64; 2]) -> (DVec3, DVec3);
    /// Surface area, world units².
    fn area(&self) -> f64;
}

/// Reads mesh `index` (0 but for `serialized`) of a file: path, index, the
/// field naming the file (for errors), the most triangles it may hold, the
/// budget its readers reserve from.
pub(crate) type ReadMesh = fn(&Path, u32, &str, usize, &Budget) -> Result<MeshData, SceneError>;

/// What a plugin's [`Plugin::build`] is given beside its document.
pub(crate) struct Input<'a> {
    /// The shape's field path, e.g. `shapes[2]`.
    pub field: &'a str,
    /// Local to world.
    pub to_world: &'a DAffine3,
    /// The mesh read from its `filename` (plugins with a
    /// [`Plugin::MESH_FILE`]), `None` when it names none.
    pub mesh_file: Option<&'a MeshData>,
    /// How many more triangles the scene may hold.
    pub max_triangles: usize,
}

/// A shape's geometry as its plugin builds it.
pub(crate) enum Local<'a> {
    /// A mesh in local coordinates, which the loader places with the
    /// shape's `to_world` (`flip_tex_coords`: each `v` becomes `1 − v`).
    Mesh {
        data: Cow<'a, MeshData>,
        flip_tex_coords: bool,
    },
    /// Analytic geometry in world space.
    Analytic(Arc<dyn Surface>),
}

/// One registered plugin, as the loader dispatches to it.
pub(crate) struct Entry {
    pub name: &'static str,
    pub fields: &'static [&'static str],
    pub mesh_file: Option<ReadMesh>,
    pub mitsuba: bool,
    pub fixed_triangles: usize,
    pub mesh_index: fn(&ShapeFields) -> Result<u32, SceneError>,
    pub inline_triangles: fn(&ShapeFields) -> Result<usize, SceneError>,
    pub build: for<'a> fn(&ShapeFields<'a>, &Input<'a>) -> Result<Local<'a>, SceneError>,
}

/// The `shapes` plugins: `Variant(file::Type) = "name"`, one line each.
/// For each line the macro declares `pub mod file;` (the plugin's file)
/// and its [`Entry`]; a shape's `type` ([`ShapeKind`]) is its index in the
/// registry, (de)serialised as the plugin's name.
macro_rules! plugins {
    ($($variant:ident($file:ident::$plugin:ident) = $name:literal,)*) => {
        $(pub mod $file;)*

        /// Every shape plugin, in registry order.
        const PLUGINS: &[Entry] = &[
            $(Entry {
                name: $name,
                fields: <$file::$plugin as Plugin>::FIELDS,
                mesh_file: <$file::$plugin as Plugin>::MESH_FILE,
                mitsuba: <$file::$plugin as Plugin>::MITSUBA,
                fixed_triangles: <$file::$plugin as Plugin>::FIXED_TRIANGLES,
                mesh_index: <$file::$plugin as Plugin>::mesh_index,
                inline_triangles: <$file::$plugin as Plugin>::inline_triangles,
                build: <$file::$plugin as Plugin>::build,
            },)*
        ];

        /// The plugin names, as serde wants them for its messages.
        const NAMES: &[&str] = &[$($name,)*];
    };
}

// The order is the scene format's (docs/scene-format.md) and the one
// serde's "expected one of" messages list.
plugins! {
    Rectangle(rectangle::RectangleShape) = "rectangle",
    Cube(cube::CubeShape) = "cube",
    Sphere(sphere::SphereShape) = "sphere",
    Disk(disk::DiskShape) = "disk",
    Cylinder(cylinder::CylinderShape) = "cylinder",
    Obj(obj::ObjShape) = "obj",
    Ply(ply::PlyShape) = "ply",
    Serialized(serialized::SerializedShape) = "serialized",
    Triangles(triangles::TrianglesShape) = "triangles",
}

/// The shape plugin names a scene's `shapes` accept, for docs.
pub fn plugin_names() -> Vec<&'static str> {
    NAMES.to_vec()
}

impl Entry {
    /// Refuses a document parameter the plugin does not take, naming it.
    pub(crate) fn check_fields(&self, fields: &ShapeFields) -> Result<(), SceneError> {
        match fields
            .doc
            .params
            .keys()
            .find(|k| !self.fields.contains(&k.as_str()))
        {
            Some(name) => Err(SceneError::invalid(
                fields.path(name),
                format!("not a field of a {}", self.name),
            )),
            None => Ok(()),
        }
    }
}

impl ShapeKind {
    /// The plugin named `name`.
    pub(crate) fn named(name: &str) -> Option<ShapeKind> {
        NAMES.iter().position(|n| *n == name).map(ShapeKind)
    }

    /// Its plugin.
    pub(crate) fn plugin(self) -> &'static Entry {
        &PLUGINS[self.0]
    }
}

// A kind (de)serialises as a unit variant named after its plugin, exactly
// as the derived enum it replaces did (the scene digest hashes the
// serialised document; serde's messages list `NAMES`).
impl Serialize for ShapeKind {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_unit_variant("ShapeKind", self.0 as u32, NAMES[self.0])
    }
}

impl<'de> Deserialize<'de> for ShapeKind {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        /// The variant's name (what a derived enum's field visitor reads).
        struct Name(ShapeKind);
        impl<'de> Deserialize<'de> for Name {
            fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                deserializer.deserialize_identifier(NameVisitor)
            }
        }
        struct NameVisitor;
        impl Visitor<'_> for NameVisitor {
            type Value = Name;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("variant identifier")
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Name, E> {
                match usize::try_from(v) {
                    Ok(i) if i < NAMES.len() => Ok(Name(ShapeKind(i))),
                    _ => Err(E::invalid_value(
                        Unexpected::Unsigned(v),
                        &format!("variant index 0 <= i < {}", NAMES.len()).as_str(),
                    )),
                }
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Name, E> {
                ShapeKind::named(v)
                    .map(Name)
                    .ok_or_else(|| E::unknown_variant(v, NAMES))
            }
            fn visit_bytes<E: de::Error>(self, v: &[u8]) -> Result<Name, E> {
                self.visit_str(&String::from_utf8_lossy(v))
            }
        }
        struct KindVisitor;
        impl<'de> Visitor<'de> for KindVisitor {
            type Value = ShapeKind;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("enum ShapeKind")
            }
            fn visit_enum<A: EnumAccess<'de>>(self, data: A) -> Result<ShapeKind, A::Error> {
                let (Name(kind), variant) = data.variant()?;
                variant.unit_variant()?;
                Ok(kind)
            }
        }
        deserializer.deserialize_enum("ShapeKind", NAMES, KindVisitor)
    }
}

/// The local mesh of a mesh-file plugin (`obj`, `ply`, `serialized`): the
/// file's mesh, whose normals `face_normals` discards (as in Mitsuba) and
/// which gets smooth ones where the file has none; `flip_tex_coords`
/// defaults to `flip_default`.
pub(crate) fn file_mesh<'a>(
    fields: &ShapeFields,
    input: &Input<'a>,
    flip_default: bool,
) -> Result<Local<'a>, SceneError> {
    // Read while sizing the scene (the loader's `build`); none where the
    // shape names no file.
    let data = input.mesh_file.ok_or_else(|| fields.missing("filename"))?;
    let face_normals = fields.boolean("face_normals")?.unwrap_or(false);
    let data = match (face_normals, data.normals.is_some()) {
        (true, true) => Cow::Owned(MeshData {
            normals: None,
            ..data.clone()
        }),
        (false, false) => Cow::Owned(data.clone().with_smooth_normals()),
        _ => Cow::Borrowed(data),
    };
    Ok(Local::Mesh {
        data,
        flip_tex_coords: fields.boolean("flip_tex_coords")?.unwrap_or(flip_default),
    })
}

#[derive(Clone, Debug)]
pub(crate) enum Geometry {
    /// Triangles `first .. first + count` of the scene's triangle list, with
    /// the cumulative area fractions used to pick one by area.
    Mesh {
        first: usize,
        count: usize,
        cdf: Vec<f64>,
    },
    /// A plugin's analytic surface.
    Analytic(Arc<dyn Surface>),
}

#[derive(Clone, Debug)]
pub(crate) struct Shape {
    pub geometry: Geometry,
    pub material: usize,
    pub emitter: Option<usize>,
    /// Analytic shapes only (meshes are re-wound at load): front side is −normal.
    pub flip: bool,
    /// Surface area in world units².
    pub area: f64,
}

/// Triangle in world space (authoring order), for sampling and hit details.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Triangle {
    pub p: [DVec3; 3],
    pub shape: u32,
    /// Index of the triangle within its shape.
    pub primitive: u32,
    /// Index into the scene's vertex normal triples, or `u32::MAX` if none.
    pub normals: u32,
    /// Index into the scene's texture coordinate triples, or `u32::MAX`
    /// if none.
    pub uvs: u32,
}

impl Triangle {
    pub fn area(&self) -> f64 {
        0.5 * (self.p[1] - self.p[0])
            .cross(self.p[2] - self.p[0])
            .length()
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.p)
    }

    /// Point with barycentrics (1 − u − v, u, v).
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        TriangleAccel::new(self).point(u, v)
    }

    pub fn normal(&self) -> DVec3 {
        TriangleAccel::new(self).normal()
    }
}

/// Triangle in the form the intersection test wants, stored in BVH order.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleAccel {
    pub v0: DVec3,
    pub e1: DVec3,
    pub e2: DVec3,
}

/// What a hit on a triangle reports beyond its geometry, stored in BVH
/// order next to [`TriangleAccel`] so a hit reads one more cache line, not
/// the authoring-order [`Triangle`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleTag {
    pub shape: u32,
    pub primitive: u32,
    /// Index into the scene's vertex normal triples, or `u32::MAX` if none.
    pub normals: u32,
    /// Index into the scene's texture coordinate triples, or `u32::MAX`.
    pub uvs: u32,
}

impl TriangleTag {
    pub fn new(t: &Triangle) -> Self {
        Self {
            shape: t.shape,
            primitive: t.primitive,
            normals: t.normals,
            uvs: t.uvs,
        }
    }
}

impl TriangleAccel {
    pub fn new(t: &Triangle) -> Self {
        Self {
            v0: t.p[0],
            e1: t.p[1] - t.p[0],
            e2: t.p[2] - t.p[0],
        }
    }

    /// Point with barycentrics (1 − u − v, u, v).
    #[inline]
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        self.v0 + self.e1 * u + self.e2 * v
    }

    /// Unit normal of the winding (v0, v0 + e1, v0 + e2).
    #[inline]
    pub fn normal(&self) -> DVec3 {
        self.e1.cross(self.e2).normalize()
    }

    /// Möller–Trumbore ("Fast, Minimum Storage Ray/Triangle Intersection",
    /// 1997) in f64: `(t, u, v)` for a hit with `0 < t < t_max`. Edges are
    /// inclusive, so rays through a shared edge hit one of its triangles.
    #[inline(always)]
    pub fn intersect(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<(f64, f64, f64)> {
        // One early exit, on the first barycentric, and the other
        // conditions combined without branches: on incoherent rays each
        // exit is a coin flip for the branch predictor (measured within a
        // few per cent of the all-branches and no-branch forms on both the
        // Cornell box and the mesh). A ray parallel to the plane has
        // `det == 0`, an infinite `inv` and so an infinite or NaN `u`,
        // which the first test rejects.
        let p = d.cross(self.e2);
        let det = self.e1.dot(p);
        let inv = 1.0 / det;
        let s = o - self.v0;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = d.dot(q) * inv;
        let t = self.e2.dot(q) * inv;
        let hit = (v >= 0.0) & (u + v <= 1.0) & (t > 0.0) & (t < t_max);
        hit.then_some((t, u, v))
    }
}

impl Shape {
    /// World bounds of an analytic shape (meshes are bounded per triangle).
    pub fn analytic_bounds(&self) -> Aabb {
        match &self.geometry {
            Geometry::Analytic(surface) => surface.bounds(),
            Geometry::Mesh { .. } => Aabb::EMPTY,
        }
    }

    /// Distance to an analytic shape along a unit-direction ray, if in (0, t_max).
    #[inline]
    pub fn intersect_analytic(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<f64> {
        match &self.geometry {
            Geometry::Analytic(surface) => surface.intersect(o, d, t_max),
            Geometry::Mesh { .. } => None,
        }
    }

    /// Surface point, front normal, texture coordinates and `[∂p/∂u,
    /// ∂p/∂v]` (`SurfaceHit::dp_du`) of an analytic hit at `t`.
    pub fn analytic_hit(&self, o: DVec3, d: DVec3, t: f64) -> (DVec3, DVec3, DVec2, [DVec3; 2]) {
        let (p, n, uv, dp) = match &self.geometry {
            Geometry::Analytic(surface) => surface.hit(o, d, t),
            Geometry::Mesh { .. } => (o + d * t, DVec3::Z, DVec2::ZERO, [DVec3::ZERO; 2]),
        };
        (p, if self.flip { -n } else { n }, uv, dp)
    }

    /// Uniform point by area on an analytic shape: (point, front normal).
    pub fn sample_analytic(&self, u: [f64; 2]) -> (DVec3, DVec3) {
        let (p, n) = match &self.geometry {
            Geometry::Analytic(surface) => surface.sample(u),
            Geometry::Mesh { .. } => (DVec3::ZERO, DVec3::Z),
        };
        (p, if self.flip { -n } else { n })
    }
}

/// The azimuth of `(x, y)` as a fraction of a turn, in [0, 1).
pub(crate) fn azimuth(y: f64, x: f64) -> f64 {
    y.atan2(x).rem_euclid(2.0 * PI) / (2.0 * PI)
}

/// Shirley & Chiu's concentric map of [0,1)² onto the unit disk
/// ("A Low Distortion Map Between Disk and Square", 1997); area-preserving.
pub(crate) fn concentric_disk(u: [f64; 2]) -> DVec2 {
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return DVec2::ZERO;
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, PI / 4.0 * (b / a))
    } else {
        (b, PI / 2.0 - PI / 4.0 * (a / b))
    };
    let (s, c) = phi.sin_cos();
    DVec2::new(r * c, r * s)
}

/// Barycentrics `(b1, b2)` uniform by area over a triangle, from `u` in
/// [0,1)², by the square-root warp (Osada et al., "Shape Distributions", 2002).
pub(crate) fn sample_barycentric(u: [f64; 2]) -> (f64, f64) {
    let su = u[0].sqrt();
    (su * (1.0 - u[1]), su * u[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_intersection_reports_barycentrics() {
        let t = Triangle {
            p: [DVec3::ZERO, DVec3::X, DVec3::Y],
            shape: 0,
            primitive: 0,
            normals: u32::MAX,
            uvs: u32::MAX,
        };
        let a = TriangleAccel::new(&t);
        let o = DVec3::new(0.25, 0.5, 1.0);
        let (d, u, v) = a.intersect(o, -DVec3::Z, 10.0).unwrap();
        assert!((d - 1.0).abs() < 1e-15 && (u - 0.25).abs() < 1e-15 && (v - 0.5).abs() < 1e-15);
        assert_eq!(t.point(u, v), DVec3::new(0.25, 0.5, 0.0));
        assert!(
            a.intersect(DVec3::new(0.75, 0.5, 1.0), -DVec3::Z, 10.0)
                .is_none()
        );
        assert!(a.intersect(o, DVec3::Z, 10.0).is_none());
        assert_eq!(t.normal(), DVec3::Z);
        // In the plane (det = 0), through the triangle or from its vertex.
        for o in [DVec3::new(-1.0, 0.25, 0.0), DVec3::ZERO] {
            assert!(a.intersect(o, DVec3::X, 10.0).is_none());
        }
        // Beyond t_max, and behind the origin.
        assert!(a.intersect(o, -DVec3::Z, 0.5).is_none());
        assert!(
            a.intersect(DVec3::new(0.25, 0.5, -1.0), -DVec3::Z, 10.0)
                .is_none()
        );
    }
}
