//! The scene's geometry as a JSON document's shapes describe it: the
//! builder that places each shape in the world (its fields checked, its
//! mesh transformed into world-space triangles, or its analytic geometry)
//! and finally builds the BVHs ([`GeometryBuilder`]), and the shapes given
//! by their parameters: inline triangle lists and spheres.

use glam::{DAffine3, DMat3, DVec2, DVec3};

use super::reject_fields;
use crate::scene::bvh::{Aabb, Bvh};
use crate::scene::digest::SceneDigest;
use crate::scene::error::SceneError;
use crate::scene::format::{ShapeDoc, ShapeKind};
use crate::scene::mesh::{self, MeshData};
use crate::scene::shape::{self, Geometry, Shape, Triangle, TriangleAccel, TriangleTag};
use crate::scene::{Camera, MAX_TRIANGLES, Scene, transform};

/// Accumulates shapes and world-space triangles, then builds the BVHs.
#[derive(Default)]
pub(super) struct GeometryBuilder {
    pub(super) shapes: Vec<Shape>,
    pub(super) triangles: Vec<Triangle>,
    pub(super) vertex_normals: Vec<[DVec3; 3]>,
    pub(super) vertex_uvs: Vec<[DVec2; 3]>,
}

/// How a shape places a local mesh.
struct Placement {
    to_world: DAffine3,
    flip_normals: bool,
    /// Replace each texture coordinate `v` by `1 − v`.
    flip_tex_coords: bool,
}

impl GeometryBuilder {
    pub(super) fn add_shape(
        &mut self,
        s: &ShapeDoc,
        field: &str,
        material: usize,
        emitter: Option<usize>,
        mesh_file: Option<&MeshData>,
    ) -> Result<(), SceneError> {
        let to_world = match &s.to_world {
            Some(t) => transform::build(t, &format!("{field}.to_world"))?,
            None => DAffine3::IDENTITY,
        };
        let kind = format!("{:?}", s.kind).to_lowercase();
        let sphere_fields = [
            ("center", s.center.is_some()),
            ("radius", s.radius.is_some()),
        ];
        let inline_fields = [
            ("positions", s.positions.is_some()),
            ("indices", s.indices.is_some()),
            ("normals", s.normals.is_some()),
            ("uvs", s.uvs.is_some()),
        ];
        let file_field = [
            ("filename", s.filename.is_some()),
            ("face_normals", s.face_normals.is_some()),
        ];
        let mesh_field = [("flip_tex_coords", s.flip_tex_coords.is_some())];
        let serialized_field = [("shape_index", s.shape_index.is_some())];
        let (reject_sphere, reject_inline, reject_file) = match s.kind {
            ShapeKind::Sphere => (false, true, true),
            ShapeKind::Triangles => (true, false, true),
            ShapeKind::Obj | ShapeKind::Ply | ShapeKind::Serialized => (true, true, false),
            _ => (true, true, true),
        };
        let reject_mesh = reject_inline && reject_file;
        for (reject, fields) in [
            (reject_sphere, &sphere_fields[..]),
            (reject_inline, &inline_fields[..]),
            (reject_file, &file_field[..]),
            (reject_mesh, &mesh_field[..]),
            (s.kind != ShapeKind::Serialized, &serialized_field[..]),
        ] {
            if reject {
                reject_fields(field, &kind, fields)?;
            }
        }
        let remaining = MAX_TRIANGLES - self.triangles.len();
        let placement = Placement {
            to_world,
            flip_normals: s.flip_normals,
            flip_tex_coords: s.flip_tex_coords.unwrap_or(s.kind == ShapeKind::Obj),
        };
        let (geometry, area) = match s.kind {
            ShapeKind::Rectangle => self.add_mesh(&mesh::rectangle(), &placement, field)?,
            ShapeKind::Cube => self.add_mesh(&mesh::cube(), &placement, field)?,
            ShapeKind::Obj | ShapeKind::Ply | ShapeKind::Serialized => {
                // Read while sizing the scene (see `build`); none where the
                // shape names no file.
                let data = mesh_file
                    .ok_or_else(|| SceneError::invalid(field, "missing field `filename`"))?;
                // `face_normals` discards the file's normals, as in Mitsuba;
                // without it a mesh that has none gets smooth ones.
                match (s.face_normals == Some(true), data.normals.is_some()) {
                    (true, true) => {
                        let flat = MeshData {
                            normals: None,
                            ..data.clone()
                        };
                        self.add_mesh(&flat, &placement, field)?
                    }
                    (false, false) => {
                        let smooth = data.clone().with_smooth_normals();
                        self.add_mesh(&smooth, &placement, field)?
                    }
                    _ => self.add_mesh(data, &placement, field)?,
                }
            }
            ShapeKind::Triangles => {
                let data = inline_mesh(s, field, remaining)?;
                self.add_mesh(&data, &placement, field)?
            }
            ShapeKind::Sphere => sphere(s, &to_world, field)?,
            ShapeKind::Disk => {
                let normal = (transform::normal_matrix(&to_world) * DVec3::Z).normalize();
                let geometry = Geometry::Disk {
                    to_world,
                    to_local: to_world.inverse(),
                    normal,
                };
                (geometry, shape::disk_area(&to_world))
            }
        };
        if !(area > 0.0 && area.is_finite()) {
            return Err(SceneError::invalid(
                field,
                format!("surface area is {area}"),
            ));
        }
        self.shapes.push(Shape {
            geometry,
            material,
            emitter,
            flip: s.flip_normals,
            area,
        });
        Ok(())
    }

    /// Places a local mesh in the world as this shape's triangles.
    ///
    /// Front sides follow the authored normal through the normal transform:
    /// a mirroring `to_world` (negative determinant) would reverse the
    /// winding, so it is swapped back. Triangles whose vertex normals all
    /// disagree with the winding are re-wound to face the vertex normals.
    fn add_mesh(
        &mut self,
        data: &MeshData,
        placement: &Placement,
        field: &str,
    ) -> Result<(Geometry, f64), SceneError> {
        let (to_world, flip) = (&placement.to_world, placement.flip_normals);
        let shape_index = self.shapes.len() as u32;
        let uvs: Option<Vec<DVec2>> = data.uvs.as_ref().map(|uvs| {
            uvs.iter()
                .map(|uv| match placement.flip_tex_coords {
                    true => DVec2::new(uv.x, 1.0 - uv.y),
                    false => *uv,
                })
                .collect()
        });
        let positions: Vec<DVec3> = data
            .positions
            .iter()
            .map(|p| to_world.transform_point3(*p))
            .collect();
        let normal_matrix = transform::normal_matrix(to_world);
        let normals: Option<Vec<DVec3>> = data.normals.as_ref().map(|ns| {
            ns.iter()
                .map(|n| (normal_matrix * *n).try_normalize().unwrap_or(DVec3::ZERO))
                .collect()
        });
        let mirrored = to_world.matrix3.determinant() < 0.0;
        let first = self.triangles.len();
        let mut cdf = Vec::with_capacity(data.indices.len());
        let mut total = 0.0;
        for (k, idx) in data.indices.iter().enumerate() {
            let mut idx = idx.map(|i| i as usize);
            if mirrored {
                idx.swap(1, 2);
            }
            let mut p = idx.map(|i| positions[i]);
            let mut ns = normals.as_ref().map(|ns| idx.map(|i| ns[i]));
            let mut ts = uvs.as_ref().map(|ts| idx.map(|i| ts[i]));
            let rewind = |p: &mut [DVec3; 3], ts: &mut Option<[DVec2; 3]>| {
                p.swap(1, 2);
                if let Some(t) = ts {
                    t.swap(1, 2);
                }
            };
            if let Some(n) = ns
                && (p[1] - p[0]).cross(p[2] - p[0]).dot(n[0] + n[1] + n[2]) < 0.0
            {
                rewind(&mut p, &mut ts);
                ns = Some([n[0], n[2], n[1]]);
            }
            if flip {
                rewind(&mut p, &mut ts);
                ns = ns.map(|n| [-n[0], -n[2], -n[1]]);
            }
            if !p.iter().all(|v| v.is_finite()) {
                return Err(SceneError::invalid(
                    field,
                    format!("triangle {k} is not finite after to_world"),
                ));
            }
            let normals_index = match ns {
                Some(n) => {
                    self.vertex_normals.push(n);
                    (self.vertex_normals.len() - 1) as u32
                }
                None => u32::MAX,
            };
            let uvs_index = match ts {
                Some(t) => {
                    self.vertex_uvs.push(t);
                    (self.vertex_uvs.len() - 1) as u32
                }
                None => u32::MAX,
            };
            let tri = Triangle {
                p,
                shape: shape_index,
                primitive: k as u32,
                normals: normals_index,
                uvs: uvs_index,
            };
            total += tri.area();
            cdf.push(total);
            self.triangles.push(tri);
        }
        if total > 0.0 {
            cdf.iter_mut().for_each(|c| *c /= total);
        }
        let count = self.triangles.len() - first;
        Ok((Geometry::Mesh { first, count, cdf }, total))
    }

    pub(super) fn finish(self) -> Scene {
        let bounds: Vec<Aabb> = self.triangles.iter().map(Triangle::bounds).collect();
        let (triangle_bvh, order) = Bvh::build(&bounds);
        let in_order = || order.iter().map(|&i| &self.triangles[i as usize]);
        let accel = in_order().map(TriangleAccel::new).collect();
        let accel_tags = in_order().map(TriangleTag::new).collect();
        let analytic: Vec<u32> = (0..self.shapes.len() as u32)
            .filter(|&i| !matches!(self.shapes[i as usize].geometry, Geometry::Mesh { .. }))
            .collect();
        let analytic_bounds: Vec<Aabb> = analytic
            .iter()
            .map(|&i| self.shapes[i as usize].analytic_bounds())
            .collect();
        let (analytic_bvh, analytic_order) = Bvh::build(&analytic_bounds);
        let analytic_shapes = analytic_order
            .iter()
            .map(|&i| analytic[i as usize])
            .collect();
        let all = bounds
            .iter()
            .chain(&analytic_bounds)
            .fold(Aabb::EMPTY, |a, b| a.union(*b));
        Scene {
            name: String::new(),
            digest: SceneDigest::default(),
            files: Vec::new(),
            materials: Vec::new(),
            material_ids: Vec::new(),
            emitters: Vec::new(),
            environment: None,
            camera: Camera::new(DAffine3::IDENTITY, 45.0, Default::default(), 1, 1),
            hide_emitters: false,
            max_depth: None,
            shapes: self.shapes,
            triangles: self.triangles,
            vertex_normals: self.vertex_normals,
            vertex_uvs: self.vertex_uvs,
            accel,
            accel_tags,
            triangle_bvh,
            analytic_bvh,
            analytic_shapes,
            bounds: all,
        }
    }
}

fn inline_mesh(s: &ShapeDoc, field: &str, max_triangles: usize) -> Result<MeshData, SceneError> {
    let missing = |name: &str| SceneError::invalid(field, format!("missing field `{name}`"));
    let positions = s.positions.as_ref().ok_or_else(|| missing("positions"))?;
    let indices = s.indices.as_ref().ok_or_else(|| missing("indices"))?;
    if indices.is_empty() || indices.len() > max_triangles {
        return Err(SceneError::invalid(
            format!("{field}.indices"),
            format!("{} triangles; need 1..={max_triangles}", indices.len()),
        ));
    }
    let positions = positions
        .iter()
        .enumerate()
        .map(|(i, p)| transform::check_vec3(p, &format!("{field}.positions[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    let mut out = Vec::with_capacity(indices.len());
    for (k, tri) in indices.iter().enumerate() {
        for (j, &i) in tri.iter().enumerate() {
            if i as usize >= positions.len() {
                return Err(SceneError::invalid(
                    format!("{field}.indices[{k}][{j}]"),
                    format!("vertex {i} does not exist ({} positions)", positions.len()),
                ));
            }
        }
        out.push(tri.map(|i| i as u32));
    }
    let normals = match &s.normals {
        None => None,
        Some(ns) => {
            if ns.len() != positions.len() {
                return Err(SceneError::invalid(
                    format!("{field}.normals"),
                    format!("{} normals for {} positions", ns.len(), positions.len()),
                ));
            }
            let mut out = Vec::with_capacity(ns.len());
            for (i, n) in ns.iter().enumerate() {
                let f = format!("{field}.normals[{i}]");
                let n = transform::check_vec3(n, &f)?
                    .try_normalize()
                    .ok_or_else(|| SceneError::invalid(f, "zero-length normal"))?;
                out.push(n);
            }
            Some(out)
        }
    };
    let uvs = match &s.uvs {
        None => None,
        Some(uvs) => {
            let f = format!("{field}.uvs");
            if uvs.len() != positions.len() {
                return Err(SceneError::invalid(
                    f,
                    format!("{} uvs for {} positions", uvs.len(), positions.len()),
                ));
            }
            if let Some(i) = uvs.iter().position(|uv| !uv.iter().all(|x| x.is_finite())) {
                return Err(SceneError::invalid(format!("{f}[{i}]"), "not finite"));
            }
            Some(uvs.iter().map(|&uv| DVec2::from(uv)).collect())
        }
    };
    Ok(MeshData {
        positions,
        indices: out,
        normals,
        uvs,
    })
}

fn sphere(s: &ShapeDoc, to_world: &DAffine3, field: &str) -> Result<(Geometry, f64), SceneError> {
    let center = transform::check_vec3(&s.center.unwrap_or([0.0; 3]), &format!("{field}.center"))?;
    let radius = s.radius.unwrap_or(1.0);
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(SceneError::invalid(
            format!("{field}.radius"),
            format!("{radius} is not a positive radius"),
        ));
    }
    let scale = similarity_scale(&to_world.matrix3).ok_or_else(|| {
        SceneError::invalid(
            format!("{field}.to_world"),
            "a sphere's transform must be a similarity (rotation, uniform scale, translation); use a mesh for ellipsoids",
        )
    })?;
    let radius = radius * scale;
    let geometry = Geometry::Sphere {
        center: to_world.transform_point3(center),
        radius,
        to_local: (to_world.matrix3 / scale).transpose(),
    };
    Ok((geometry, 4.0 * std::f64::consts::PI * radius * radius))
}

/// The uniform scale `s` if `m = s·R` with `R` orthogonal (to 1e-6).
pub(super) fn similarity_scale(m: &DMat3) -> Option<f64> {
    let cols = [m.x_axis, m.y_axis, m.z_axis];
    let s = cols[0].length();
    let tol = 1e-6 * s * s;
    let ok = cols
        .iter()
        .all(|c| (c.length_squared() - s * s).abs() <= tol)
        && cols[0].dot(cols[1]).abs() <= tol
        && cols[1].dot(cols[2]).abs() <= tol
        && cols[0].dot(cols[2]).abs() <= tol;
    ok.then_some(s)
}
