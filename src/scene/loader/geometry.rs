//! The scene's geometry as a JSON document's shapes describe it: the
//! builder that places each shape in the world (its fields checked, its
//! mesh transformed into world-space triangles, or its analytic geometry)
//! and finally builds the BVHs ([`GeometryBuilder`]). Each shape's own
//! geometry is its plugin's (`scene::shape`).

use glam::{DAffine3, DVec2, DVec3};

use crate::scene::bvh::{Aabb, Bvh};
use crate::scene::digest::SceneDigest;
use crate::scene::error::SceneError;
use crate::scene::format::ShapeDoc;
use crate::scene::mesh::MeshData;
use crate::scene::shape::{
    Geometry, Input, Local, Shape, ShapeFields, Triangle, TriangleAccel, TriangleTag,
};
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
        let plugin = s.kind.plugin();
        let input = Input {
            field,
            to_world: &to_world,
            mesh_file,
            max_triangles: MAX_TRIANGLES - self.triangles.len(),
        };
        let fields = ShapeFields { doc: s, field };
        let (geometry, area) = match (plugin.build)(&fields, &input)? {
            Local::Mesh {
                data,
                flip_tex_coords,
            } => {
                let placement = Placement {
                    to_world,
                    flip_normals: s.flip_normals,
                    flip_tex_coords,
                };
                self.add_mesh(&data, &placement, field)?
            }
            Local::Analytic(surface) => {
                let area = surface.area();
                (Geometry::Analytic(surface), area)
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
            meters: Vec::new(),
            environment: None,
            camera: Camera::new(DAffine3::IDENTITY, 45.0, Default::default(), 1, 1),
            hide_emitters: false,
            max_depth: None,
            caustic_surfaces: false,
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
