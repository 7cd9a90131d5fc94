//! `sphere`: an analytic sphere, outward normal.
//!
//! Parameters: `center` (local coordinates, default the origin), `radius`
//! (local units, default 1). Its `to_world` must be a similarity
//! (rotation, uniform scale, translation): the sphere is intersected
//! exactly, so an ellipsoid needs a mesh.

use std::f64::consts::PI;
use std::sync::Arc;

use glam::{DMat3, DVec2, DVec3};

use super::{Input, Local, Plugin, ShapeFields, Surface, azimuth};
use crate::scene::bvh::Aabb;
use crate::scene::error::SceneError;
use crate::scene::transform;

/// The sphere plugin; see the module docs.
pub struct SphereShape;

impl Plugin for SphereShape {
    const FIELDS: &'static [&'static str] = &["center", "radius"];

    fn build<'a>(fields: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        let to_world = input.to_world;
        let center = DVec3::from(fields.vec3("center")?.unwrap_or([0.0; 3]));
        let radius = fields.number("radius")?.unwrap_or(1.0);
        if !(radius > 0.0 && radius.is_finite()) {
            return Err(SceneError::invalid(
                fields.path("radius"),
                format!("{radius} is not a positive radius"),
            ));
        }
        let scale = transform::similarity_scale(&to_world.matrix3).ok_or_else(|| {
            SceneError::invalid(
                format!("{}.to_world", input.field),
                "a sphere's transform must be a similarity (rotation, uniform scale, translation); use a mesh for ellipsoids",
            )
        })?;
        Ok(Local::Analytic(Arc::new(Sphere {
            center: to_world.transform_point3(center),
            radius: radius * scale,
            to_local: (to_world.matrix3 / scale).transpose(),
        })))
    }
}

/// A sphere in world space.
#[derive(Debug)]
struct Sphere {
    center: DVec3,
    radius: f64,
    /// The rotation from world to the sphere's own frame, whose z axis is
    /// the texture's pole (Mitsuba 3's parametrisation).
    to_local: DMat3,
}

impl Surface for Sphere {
    fn bounds(&self) -> Aabb {
        Aabb {
            min: self.center - DVec3::splat(self.radius),
            max: self.center + DVec3::splat(self.radius),
        }
    }

    fn intersect(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<f64> {
        // Hearn & Baker's form of the discriminant, which stays accurate
        // for distant spheres (Ray Tracing Gems ch. 7).
        let r = self.radius;
        let oc = o - self.center;
        let b = oc.dot(d);
        let f = oc - d * b;
        let disc = r * r - f.length_squared();
        if disc < 0.0 {
            return None;
        }
        let c = oc.length_squared() - r * r;
        let q = -b - disc.sqrt().copysign(b);
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
        let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        [near, far].into_iter().find(|&t| t > 0.0 && t < t_max)
    }

    /// Texture coordinates follow Mitsuba 3: `(φ/2π, θ/π)` of the local
    /// direction (θ from the local +z pole, φ from +x towards +y); ∂p/∂u
    /// runs along the azimuth, ∂p/∂v towards the −z pole (at a pole,
    /// along local x, as Mitsuba's).
    fn hit(&self, o: DVec3, d: DVec3, t: f64) -> (DVec3, DVec3, DVec2, [DVec3; 2]) {
        let n = (o + d * t - self.center).normalize();
        let l = self.to_local * n;
        let uv = DVec2::new(azimuth(l.y, l.x), l.z.clamp(-1.0, 1.0).acos() / PI);
        let rd = l.x.hypot(l.y);
        let dv = if rd > 0.0 {
            DVec3::new(l.z * l.x / rd, l.z * l.y / rd, -rd)
        } else {
            DVec3::X
        };
        let to_world = self.to_local.transpose() * self.radius;
        let dp = [
            to_world * DVec3::new(-l.y, l.x, 0.0) * (2.0 * PI),
            to_world * dv * PI,
        ];
        (self.center + n * self.radius, n, uv, dp)
    }

    fn sample(&self, u: [f64; 2]) -> (DVec3, DVec3) {
        let z = 1.0 - 2.0 * u[0];
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (s, c) = (2.0 * PI * u[1]).sin_cos();
        let n = DVec3::new(r * c, r * s, z);
        (self.center + n * self.radius, n)
    }

    fn area(&self) -> f64 {
        4.0 * PI * self.radius * self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_hit_from_outside_and_inside() {
        let s = Sphere {
            center: DVec3::new(0.0, 0.0, 5.0),
            radius: 1.0,
            to_local: DMat3::IDENTITY,
        };
        assert!((s.area() - 4.0 * PI).abs() < 1e-12);
        let t = s.intersect(DVec3::ZERO, DVec3::Z, f64::INFINITY).unwrap();
        assert!((t - 4.0).abs() < 1e-12);
        let (p, n, ..) = s.hit(DVec3::ZERO, DVec3::Z, t);
        assert!((p - DVec3::new(0.0, 0.0, 4.0)).length() < 1e-12);
        assert_eq!(n, -DVec3::Z); // outward normal, not turned toward the ray
        let t = s
            .intersect(DVec3::new(0.0, 0.0, 5.0), DVec3::X, f64::INFINITY)
            .unwrap();
        assert!((t - 1.0).abs() < 1e-12);
        assert!(s.intersect(DVec3::ZERO, DVec3::Z, 3.5).is_none());
        assert!(s.intersect(DVec3::ZERO, -DVec3::Z, f64::INFINITY).is_none());
    }
}
