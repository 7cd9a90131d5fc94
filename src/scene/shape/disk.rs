//! `disk`: the analytic unit disk in the local xy plane, front normal +z.
//! No parameters of its own; any affine `to_world` (the disk becomes an
//! ellipse, still planar, its area scaled by a constant, so sampling it
//! uniformly in the local disk is uniform by area).

use std::f64::consts::PI;
use std::sync::Arc;

use glam::{DAffine3, DVec2, DVec3};

use super::{Input, Local, Plugin, ShapeFields, Surface, azimuth, concentric_disk};
use crate::scene::bvh::Aabb;
use crate::scene::error::SceneError;
use crate::scene::transform;

/// The disk plugin; see the module docs.
pub struct DiskShape;

impl Plugin for DiskShape {
    fn build<'a>(_: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        Ok(Local::Analytic(Arc::new(Disk::new(*input.to_world))))
    }
}

/// The image of the unit disk in local xy under `to_world`.
#[derive(Debug)]
struct Disk {
    to_world: DAffine3,
    to_local: DAffine3,
    /// Unit world normal of the local +z side.
    normal: DVec3,
}

impl Disk {
    fn new(to_world: DAffine3) -> Self {
        Disk {
            to_world,
            to_local: to_world.inverse(),
            normal: (transform::normal_matrix(&to_world) * DVec3::Z).normalize(),
        }
    }
}

impl Surface for Disk {
    fn bounds(&self) -> Aabb {
        let (a, b) = (self.to_world.matrix3.x_axis, self.to_world.matrix3.y_axis);
        let half = (a * a + b * b).map(f64::sqrt);
        Aabb {
            min: self.to_world.translation - half,
            max: self.to_world.translation + half,
        }
    }

    fn intersect(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<f64> {
        let ol = self.to_local.transform_point3(o);
        let dl = self.to_local.transform_vector3(d);
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

    /// Texture coordinates follow Mitsuba 3: `(r, φ/2π)` of the local
    /// point; ∂p/∂u runs outwards along the radius, ∂p/∂v along the
    /// circumference (Mitsuba's).
    fn hit(&self, o: DVec3, d: DVec3, t: f64) -> (DVec3, DVec3, DVec2, [DVec3; 2]) {
        let l = self.to_local.transform_point3(o + d * t);
        let r = l.truncate().length();
        let (c, s) = if r > 0.0 { (l.x / r, l.y / r) } else { (1.0, 0.0) };
        let dp = [
            self.to_world.transform_vector3(DVec3::new(c, s, 0.0)),
            self.to_world.transform_vector3(DVec3::new(-s, c, 0.0) * (2.0 * PI * r)),
        ];
        (
            self.to_world.transform_point3(DVec3::new(l.x, l.y, 0.0)),
            self.normal,
            DVec2::new(r, azimuth(l.y, l.x)),
            dp,
        )
    }

    fn sample(&self, u: [f64; 2]) -> (DVec3, DVec3) {
        let q = concentric_disk(u);
        let p = self.to_world.transform_point3(DVec3::new(q.x, q.y, 0.0));
        (p, self.normal)
    }

    fn area(&self) -> f64 {
        let m = &self.to_world.matrix3;
        PI * m.x_axis.cross(m.y_axis).length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shape::{Geometry, Shape};

    #[test]
    fn disk_hit_respects_radius_and_normal() {
        let to_world = DAffine3::from_translation(DVec3::new(0.0, 1.0, 0.0))
            * DAffine3::from_rotation_x(-PI / 2.0)
            * DAffine3::from_scale(DVec3::new(2.0, 1.0, 1.0));
        let disk = Disk::new(to_world);
        assert!((disk.area() - 2.0 * PI).abs() < 1e-12);
        let s = Shape {
            area: disk.area(),
            geometry: Geometry::Analytic(Arc::new(disk)),
            material: 0,
            emitter: None,
            flip: true,
        };
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
}
