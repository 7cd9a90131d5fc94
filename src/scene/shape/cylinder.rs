//! `cylinder`: an analytic open cylinder (no end caps), outward normal, as
//! Mitsuba 3's `cylinder` plugin defines it.
//!
//! Parameters: `p0` and `p1`, the ends of its axis (local coordinates,
//! default (0, 0, 0) and (0, 0, 1)), and `radius` (local units, default 1).
//! The cylinder is the unit cylinder `x² + y² = 1, 0 ≤ z ≤ 1` placed by
//! `to_world · translate(p0) · frame(p1 − p0) · scale(r, r, |p1 − p0|)`,
//! where `frame(d)` turns +z into `d` and +x, +y into the tangents of
//! Duff et al.'s basis about `d` (Mitsuba's `to_frame(Frame3f(d))`), so its
//! texture coordinates are Mitsuba's: `(φ/2π, z)`, φ from the frame's x
//! towards its y. `to_world` must be a similarity (rotation, uniform
//! scale, translation), so the cylinder stays circular.

use std::f64::consts::PI;
use std::sync::Arc;

use glam::{DAffine3, DMat3, DVec2, DVec3};

use super::{Input, Local, Plugin, ShapeFields, Surface, azimuth};
use crate::scene::bvh::Aabb;
use crate::scene::error::SceneError;
use crate::scene::transform;
use crate::sphere::Frame;

/// The cylinder plugin; see the module docs.
pub struct CylinderShape;

impl Plugin for CylinderShape {
    const FIELDS: &'static [&'static str] = &["p0", "p1", "radius"];

    fn build<'a>(fields: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        let p0 = DVec3::from(fields.vec3("p0")?.unwrap_or([0.0; 3]));
        let p1 = DVec3::from(fields.vec3("p1")?.unwrap_or([0.0, 0.0, 1.0]));
        let radius = fields.number("radius")?.unwrap_or(1.0);
        if !(radius > 0.0 && radius.is_finite()) {
            return Err(SceneError::invalid(
                fields.path("radius"),
                format!("{radius} is not a positive radius"),
            ));
        }
        let axis = p1 - p0;
        let length = axis.length();
        if !(length > 0.0 && length.is_finite()) {
            return Err(SceneError::invalid(
                fields.path("p1"),
                "the cylinder's axis has no length (p1 equals p0)",
            ));
        }
        transform::similarity_scale(&input.to_world.matrix3).ok_or_else(|| {
            SceneError::invalid(
                format!("{}.to_world", input.field),
                "a cylinder's transform must be a similarity (rotation, uniform scale, translation); use a mesh for elliptic cylinders",
            )
        })?;
        let frame = Frame::from_normal(axis / length);
        let placement = DAffine3::from_mat3_translation(
            DMat3::from_cols(frame.s * radius, frame.t * radius, frame.n * length),
            p0,
        );
        Ok(Local::Analytic(Arc::new(Cylinder::new(
            *input.to_world * placement,
        ))))
    }
}

/// The image of the unit cylinder under `to_world` (a similarity in its
/// cross-section, any length along z).
#[derive(Debug)]
struct Cylinder {
    to_world: DAffine3,
    to_local: DAffine3,
    /// Maps local normals to world normals (inverse transpose).
    normal_matrix: DMat3,
}

impl Cylinder {
    fn new(to_world: DAffine3) -> Self {
        Cylinder {
            to_world,
            to_local: to_world.inverse(),
            normal_matrix: transform::normal_matrix(&to_world),
        }
    }

    /// The world radius and length.
    fn radius_and_length(&self) -> (f64, f64) {
        let m = &self.to_world.matrix3;
        (m.x_axis.length(), m.z_axis.length())
    }
}

impl Surface for Cylinder {
    /// The smallest box holding both end circles (a circle of radius r
    /// about axis a spans `r·√(1 − a_i²)` along axis i).
    fn bounds(&self) -> Aabb {
        let (a, b) = (self.to_world.matrix3.x_axis, self.to_world.matrix3.y_axis);
        let half = (a * a + b * b).map(f64::sqrt);
        let (p0, p1) = (
            self.to_world.translation,
            self.to_world.transform_point3(DVec3::Z),
        );
        Aabb {
            min: p0.min(p1) - half,
            max: p0.max(p1) + half,
        }
    }

    fn intersect(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<f64> {
        // The local ray is o' + t d' with the world's t (the map is affine).
        let ol = self.to_local.transform_point3(o);
        let dl = self.to_local.transform_vector3(d);
        let a = dl.x * dl.x + dl.y * dl.y;
        if a == 0.0 {
            return None;
        }
        let b = ol.x * dl.x + ol.y * dl.y;
        let c = ol.x * ol.x + ol.y * ol.y - 1.0;
        let disc = b * b - a * c;
        if disc < 0.0 {
            return None;
        }
        // The stable pair of roots of a t² + 2b t + c (Numerical Recipes §5.6).
        let q = -(b + disc.sqrt().copysign(b));
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q / a) };
        let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        [near, far].into_iter().find(|&t| {
            let z = ol.z + t * dl.z;
            t > 0.0 && t < t_max && (0.0..=1.0).contains(&z)
        })
    }

    /// Texture coordinates follow Mitsuba 3: `(φ/2π, z)` of the local
    /// point; ∂p/∂u runs along the circumference, ∂p/∂v along the axis.
    fn hit(&self, o: DVec3, d: DVec3, t: f64) -> (DVec3, DVec3, DVec2, [DVec3; 2]) {
        let l = self.to_local.transform_point3(o + d * t);
        // Projected back onto the unit cylinder against round-off.
        let (x, y) = (l.x, l.y);
        let r = (x * x + y * y).sqrt();
        let (x, y) = (x / r, y / r);
        let p = self.to_world.transform_point3(DVec3::new(x, y, l.z));
        let n = (self.normal_matrix * DVec3::new(x, y, 0.0)).normalize();
        let dp = [
            self.to_world.transform_vector3(DVec3::new(-y, x, 0.0) * (2.0 * PI)),
            self.to_world.transform_vector3(DVec3::Z),
        ];
        (p, n, DVec2::new(azimuth(y, x), l.z), dp)
    }

    fn sample(&self, u: [f64; 2]) -> (DVec3, DVec3) {
        let (s, c) = (2.0 * PI * u[1]).sin_cos();
        let p = self.to_world.transform_point3(DVec3::new(c, s, u[0]));
        (p, (self.normal_matrix * DVec3::new(c, s, 0.0)).normalize())
    }

    fn area(&self) -> f64 {
        let (r, l) = self.radius_and_length();
        2.0 * PI * r * l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cylinder(p0: DVec3, p1: DVec3, radius: f64, to_world: DAffine3) -> Cylinder {
        let axis = p1 - p0;
        let frame = Frame::from_normal(axis.normalize());
        Cylinder::new(
            to_world
                * DAffine3::from_mat3_translation(
                    DMat3::from_cols(frame.s * radius, frame.t * radius, axis),
                    p0,
                ),
        )
    }

    #[test]
    fn rays_hit_the_side_within_its_ends_from_outside_and_inside() {
        // Axis along +x from (1, 0, 0) to (4, 0, 0), radius 0.5, moved up 2.
        let c = cylinder(
            DVec3::X,
            DVec3::new(4.0, 0.0, 0.0),
            0.5,
            DAffine3::from_translation(DVec3::new(0.0, 2.0, 0.0)),
        );
        assert!((c.area() - 2.0 * PI * 0.5 * 3.0).abs() < 1e-12);
        let b = c.bounds();
        assert!((b.min - DVec3::new(1.0, 1.5, -0.5)).length() < 1e-12, "{b:?}");
        assert!((b.max - DVec3::new(4.0, 2.5, 0.5)).length() < 1e-12, "{b:?}");

        let o = DVec3::new(2.0, 2.0, 5.0);
        let t = c.intersect(o, -DVec3::Z, f64::INFINITY).unwrap();
        assert!((t - 4.5).abs() < 1e-12);
        let (p, n, uv, [dp_du, dp_dv]) = c.hit(o, -DVec3::Z, t);
        assert!((p - DVec3::new(2.0, 2.0, 0.5)).length() < 1e-12);
        assert!((n - DVec3::Z).length() < 1e-12, "outward normal {n}");
        assert!((uv.y - 1.0 / 3.0).abs() < 1e-12, "{uv}");
        assert!(dp_du.dot(n).abs() < 1e-12 && dp_du.dot(DVec3::X).abs() < 1e-12);
        assert!((dp_du.length() - 2.0 * PI * 0.5).abs() < 1e-12, "{dp_du}");
        assert!((dp_dv - DVec3::new(3.0, 0.0, 0.0)).length() < 1e-12, "{dp_dv}");
        // From inside, the far wall; beyond the ends, nothing (no caps).
        let inside = DVec3::new(2.0, 2.0, 0.0);
        let t = c.intersect(inside, DVec3::Z, f64::INFINITY).unwrap();
        assert!((t - 0.5).abs() < 1e-12);
        assert!(
            c.intersect(DVec3::new(4.5, 2.0, 5.0), -DVec3::Z, f64::INFINITY)
                .is_none()
        );
        assert!(
            c.intersect(DVec3::new(0.0, 2.0, 0.0), DVec3::X, f64::INFINITY)
                .is_none()
        );
        assert!(c.intersect(o, -DVec3::Z, 4.0).is_none());
    }

    #[test]
    fn samples_are_uniform_by_area_on_the_side() {
        let c = cylinder(DVec3::ZERO, DVec3::Z * 2.0, 1.5, DAffine3::IDENTITY);
        let n = 64;
        let mut counts = [0u32; 4];
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64];
                let (p, normal) = c.sample(u);
                assert!((p.truncate().length() - 1.5).abs() < 1e-12);
                assert!((normal - p.with_z(0.0) / 1.5).length() < 1e-12);
                assert!((0.0..=2.0).contains(&p.z));
                // Quadrants of z × angle hold equal shares of the area.
                let half_z = usize::from(p.z > 1.0);
                let half_phi = usize::from(p.y > 0.0);
                counts[2 * half_z + half_phi] += 1;
            }
        }
        assert!(counts.iter().all(|&k| k == counts[0]), "{counts:?}");
    }
}
