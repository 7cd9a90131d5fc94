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
//! which of [`ShapeDoc`]'s kind-specific fields it takes, their validation
//! and its local geometry ([`Plugin`]); the `plugins!` invocation below is
//! the registry of the `shapes` plugins. The generic fields (`type`, `id`,
//! `material`, `to_world`, `emitter`, `flip_normals`) are the family's,
//! handled once by the loader. A shape document stays the typed
//! [`ShapeDoc`] (not `Params`) so that its errors keep serde's field path
//! and line/column.

use std::f64::consts::PI;

use std::borrow::Cow;
use std::path::Path;

use glam::{DAffine3, DMat3, DVec2, DVec3};
use serde::de::{self, Deserializer, EnumAccess, Unexpected, VariantAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use super::budget::Budget;
use super::bvh::Aabb;
use super::error::SceneError;
use super::format::{ShapeDoc, ShapeKind};
use super::mesh::MeshData;

/// A shape plugin: what the loader needs of one `type` of shape. Each
/// plugin's file implements it on its (unit) type.
pub(crate) trait Plugin {
    /// The kind-specific fields of [`ShapeDoc`] the plugin takes; a
    /// document giving any other is refused, naming that field.
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

    /// Triangles the document lists inline, counted before any mesh file
    /// is read (they narrow what the files may hold).
    fn inline_triangles(_doc: &ShapeDoc) -> usize {
        0
    }

    /// The shape's geometry from its validated document: a local mesh for
    /// the loader to place, or analytic geometry in world space.
    fn build<'a>(doc: &'a ShapeDoc, input: &Input<'a>) -> Result<Local<'a>, SceneError>;
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
    /// Analytic geometry in world space and its area, world units².
    Analytic(Geometry, f64),
}

/// One registered plugin, as the loader dispatches to it.
pub(crate) struct Entry {
    pub name: &'static str,
    pub fields: &'static [&'static str],
    pub mesh_file: Option<ReadMesh>,
    pub mitsuba: bool,
    pub fixed_triangles: usize,
    pub inline_triangles: fn(&ShapeDoc) -> usize,
    pub build: for<'a> fn(&'a ShapeDoc, &Input<'a>) -> Result<Local<'a>, SceneError>,
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
    Obj(obj::ObjShape) = "obj",
    Ply(ply::PlyShape) = "ply",
    Serialized(serialized::SerializedShape) = "serialized",
    Triangles(triangles::TrianglesShape) = "triangles",
}

/// The shape plugin names a scene's `shapes` accept, for docs.
pub fn plugin_names() -> Vec<&'static str> {
    NAMES.to_vec()
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
    doc: &ShapeDoc,
    input: &Input<'a>,
    flip_default: bool,
) -> Result<Local<'a>, SceneError> {
    // Read while sizing the scene (the loader's `build`); none where the
    // shape names no file.
    let data = input
        .mesh_file
        .ok_or_else(|| SceneError::invalid(input.field, "missing field `filename`"))?;
    let data = match (doc.face_normals == Some(true), data.normals.is_some()) {
        (true, true) => Cow::Owned(MeshData {
            normals: None,
            ..data.clone()
        }),
        (false, false) => Cow::Owned(data.clone().with_smooth_normals()),
        _ => Cow::Borrowed(data),
    };
    Ok(Local::Mesh {
        data,
        flip_tex_coords: doc.flip_tex_coords.unwrap_or(flip_default),
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
    /// `to_local` is the rotation from world to the sphere's own frame,
    /// whose z axis is the texture's pole (Mitsuba 3's parametrisation).
    Sphere {
        center: DVec3,
        radius: f64,
        to_local: DMat3,
    },
    /// Image of the unit disk in local xy under `to_world`.
    Disk {
        to_world: DAffine3,
        to_local: DAffine3,
        /// Unit world normal of the local +z side.
        normal: DVec3,
    },
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
            Geometry::Sphere { center, radius, .. } => Aabb {
                min: center - DVec3::splat(*radius),
                max: center + DVec3::splat(*radius),
            },
            Geometry::Disk { to_world, .. } => {
                let (a, b) = (to_world.matrix3.x_axis, to_world.matrix3.y_axis);
                let half = (a * a + b * b).map(f64::sqrt);
                Aabb {
                    min: to_world.translation - half,
                    max: to_world.translation + half,
                }
            }
            Geometry::Mesh { .. } => Aabb::EMPTY,
        }
    }

    /// Distance to an analytic shape along a unit-direction ray, if in (0, t_max).
    #[inline]
    pub fn intersect_analytic(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<f64> {
        match &self.geometry {
            Geometry::Sphere { center, radius, .. } => {
                // Hearn & Baker's form of the discriminant, which stays
                // accurate for distant spheres (Ray Tracing Gems ch. 7).
                let oc = o - *center;
                let b = oc.dot(d);
                let f = oc - d * b;
                let disc = radius * radius - f.length_squared();
                if disc < 0.0 {
                    return None;
                }
                let c = oc.length_squared() - radius * radius;
                let q = -b - disc.sqrt().copysign(b);
                let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
                let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
                [near, far].into_iter().find(|&t| t > 0.0 && t < t_max)
            }
            Geometry::Disk { to_local, .. } => {
                let ol = to_local.transform_point3(o);
                let dl = to_local.transform_vector3(d);
                if dl.z == 0.0 {
                    return None;
                }
                let t = -ol.z / dl.z;
                if !(t > 0.0 && t < t_max) {
                    return None;
                }
                let x = ol.x + t * dl.x;
                let y = ol.y + t * dl.y;
                (x * x + y * y <= 1.0).then_some(t)
            }
            Geometry::Mesh { .. } => None,
        }
    }

    /// Surface point, front normal and texture coordinates of an analytic
    /// hit at `t`, the point projected back onto the surface so the error
    /// is a few ulps. Texture coordinates follow Mitsuba 3: on a sphere
    /// `(φ/2π, θ/π)` of the local direction (θ from the local +z pole, φ
    /// from +x towards +y); on a disk `(r, φ/2π)` of the local point.
    pub fn analytic_hit(&self, o: DVec3, d: DVec3, t: f64) -> (DVec3, DVec3, DVec2, DVec3) {
        let p = o + d * t;
        let azimuth = |y: f64, x: f64| y.atan2(x).rem_euclid(2.0 * PI) / (2.0 * PI);
        // The last entry is the unit ∂p/∂u of the shape's (u, v) (module
        // docs of `SurfaceHit::dp_du`): along the azimuth on a sphere,
        // outwards along the radius on a disk.
        let (p, n, uv, dp_du) = match &self.geometry {
            Geometry::Sphere {
                center,
                radius,
                to_local,
            } => {
                let n = (p - *center).normalize();
                let l = *to_local * n;
                let uv = DVec2::new(azimuth(l.y, l.x), l.z.clamp(-1.0, 1.0).acos() / PI);
                let dp_du = to_local.transpose() * DVec3::new(-l.y, l.x, 0.0);
                (*center + n * *radius, n, uv, dp_du)
            }
            Geometry::Disk {
                to_world,
                to_local,
                normal,
            } => {
                let l = to_local.transform_point3(p);
                let dp_du = to_world.transform_vector3(DVec3::new(l.x, l.y, 0.0));
                (
                    to_world.transform_point3(DVec3::new(l.x, l.y, 0.0)),
                    *normal,
                    DVec2::new(l.truncate().length(), azimuth(l.y, l.x)),
                    dp_du,
                )
            }
            Geometry::Mesh { .. } => (p, DVec3::Z, DVec2::ZERO, DVec3::ZERO),
        };
        (
            p,
            if self.flip { -n } else { n },
            uv,
            dp_du.normalize_or_zero(),
        )
    }

    /// Uniform point by area on an analytic shape: (point, front normal).
    pub fn sample_analytic(&self, u: [f64; 2]) -> (DVec3, DVec3) {
        let (p, n) = match &self.geometry {
            Geometry::Sphere { center, radius, .. } => {
                let z = 1.0 - 2.0 * u[0];
                let r = (1.0 - z * z).max(0.0).sqrt();
                let (s, c) = (2.0 * PI * u[1]).sin_cos();
                let n = DVec3::new(r * c, r * s, z);
                (*center + n * *radius, n)
            }
            Geometry::Disk {
                to_world, normal, ..
            } => {
                let q = concentric_disk(u);
                (
                    to_world.transform_point3(DVec3::new(q.x, q.y, 0.0)),
                    *normal,
                )
            }
            Geometry::Mesh { .. } => (DVec3::ZERO, DVec3::Z),
        };
        (p, if self.flip { -n } else { n })
    }
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

/// Area of the image of the unit disk under `to_world`.
pub(crate) fn disk_area(to_world: &DAffine3) -> f64 {
    PI * to_world
        .matrix3
        .x_axis
        .cross(to_world.matrix3.y_axis)
        .length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_hit_from_outside_and_inside() {
        let s = Shape {
            geometry: Geometry::Sphere {
                center: DVec3::new(0.0, 0.0, 5.0),
                radius: 1.0,
                to_local: DMat3::IDENTITY,
            },
            material: 0,
            emitter: None,
            flip: false,
            area: 4.0 * PI,
        };
        let t = s
            .intersect_analytic(DVec3::ZERO, DVec3::Z, f64::INFINITY)
            .unwrap();
        assert!((t - 4.0).abs() < 1e-12);
        let (p, n, ..) = s.analytic_hit(DVec3::ZERO, DVec3::Z, t);
        assert!((p - DVec3::new(0.0, 0.0, 4.0)).length() < 1e-12);
        assert_eq!(n, -DVec3::Z); // outward normal, not flipped toward the ray
        let t = s
            .intersect_analytic(DVec3::new(0.0, 0.0, 5.0), DVec3::X, f64::INFINITY)
            .unwrap();
        assert!((t - 1.0).abs() < 1e-12);
        assert!(s.intersect_analytic(DVec3::ZERO, DVec3::Z, 3.5).is_none());
        assert!(
            s.intersect_analytic(DVec3::ZERO, -DVec3::Z, f64::INFINITY)
                .is_none()
        );
    }

    #[test]
    fn disk_hit_respects_radius_and_normal() {
        let to_world = DAffine3::from_translation(DVec3::new(0.0, 1.0, 0.0))
            * DAffine3::from_rotation_x(-PI / 2.0)
            * DAffine3::from_scale(DVec3::new(2.0, 1.0, 1.0));
        let s = Shape {
            geometry: Geometry::Disk {
                to_world,
                to_local: to_world.inverse(),
                normal: (to_world.matrix3.inverse().transpose() * DVec3::Z).normalize(),
            },
            material: 0,
            emitter: None,
            flip: true,
            area: disk_area(&to_world),
        };
        assert!((s.area - 2.0 * PI).abs() < 1e-12);
        // Ellipse in y = 1 with semi-axes 2 (x) and 1 (z); rotating +z by
        // −90° about x gives +y, and flip turns the front to −y.
        let o = DVec3::new(1.9, 0.0, 0.0);
        let t = s.intersect_analytic(o, DVec3::Y, 10.0).unwrap();
        assert!((t - 1.0).abs() < 1e-12);
        assert!((s.analytic_hit(o, DVec3::Y, t).1 + DVec3::Y).length() < 1e-12);
        assert!(
            s.intersect_analytic(DVec3::new(0.0, 0.0, 1.1), DVec3::Y, 10.0)
                .is_none()
        );
    }

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
