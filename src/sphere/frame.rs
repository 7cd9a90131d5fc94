//! Orthonormal shading frames.
//!
//! Every hemisphere quantity in this crate (sample sets, densities, kernel
//! means) lives in the **local frame** where `z` is the surface normal. A
//! [`Frame`] carries directions between that frame and world space.

use glam::DVec3;

/// Right-handed orthonormal basis `(s, t, n)`; `n` is the local `z` axis.
///
/// Invariant: the three axes are unit length and mutually orthogonal (to
/// within rounding), so `to_world(to_local(v)) == v` for any `v`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Local x axis (tangent).
    pub s: DVec3,
    /// Local y axis (bitangent), `n × s`.
    pub t: DVec3,
    /// Local z axis: the surface normal.
    pub n: DVec3,
}

impl Frame {
    /// Frame whose `z` axis is the unit vector `n`.
    ///
    /// Uses the branchless construction of Duff et al., "Building an
    /// Orthonormal Basis, Revisited" (JCGT 2017), which is continuous except
    /// across `n.z = 0` sign changes and has no singularity at the poles.
    /// `n` must already be normalised; callers validate user input first.
    pub fn from_normal(n: DVec3) -> Self {
        let sign = 1f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = DVec3::new(b, sign + n.y * n.y * a, -n.y);
        Self { s, t, n }
    }

    /// This frame turned by `angle` radians about its normal (counter-clockwise
    /// seen from above). Rotating a sample set about the normal leaves every
    /// kernel matrix and every Lambert kernel mean unchanged (docs/math.md §5).
    pub fn rotated_about_normal(&self, angle: f64) -> Self {
        let (sin, cos) = angle.sin_cos();
        Self {
            s: self.s * cos + self.t * sin,
            t: self.t * cos - self.s * sin,
            n: self.n,
        }
    }

    /// World-space vector expressed in this frame.
    #[inline]
    pub fn to_local(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local-frame vector expressed in world space.
    #[inline]
    pub fn to_world(&self, v: DVec3) -> DVec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn normals() -> Vec<DVec3> {
        let mut out = vec![DVec3::Z, -DVec3::Z, DVec3::X, -DVec3::Y];
        for i in 0..50 {
            let u = i as f64 / 50.0;
            let phi = 7.0 * u * std::f64::consts::TAU;
            let z = 2.0 * u - 1.0;
            let r = (1.0 - z * z).sqrt();
            out.push(DVec3::new(r * phi.cos(), r * phi.sin(), z));
        }
        out
    }

    #[test]
    fn basis_is_orthonormal_and_right_handed() {
        for n in normals() {
            let f = Frame::from_normal(n);
            for v in [f.s, f.t, f.n] {
                assert!((v.length() - 1.0).abs() < 1e-12, "{n}");
            }
            assert!(f.s.dot(f.t).abs() < 1e-12);
            assert!(f.s.dot(f.n).abs() < 1e-12);
            assert!((f.s.cross(f.t) - f.n).length() < 1e-12, "{n}");
        }
    }

    #[test]
    fn local_world_round_trip() {
        let v = DVec3::new(0.3, -0.7, 0.2);
        for n in normals() {
            let f = Frame::from_normal(n).rotated_about_normal(1.3);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-12);
            assert!((f.to_local(n) - DVec3::Z).length() < 1e-12);
        }
    }

    #[test]
    fn rotation_about_normal_keeps_elevation() {
        let f = Frame::from_normal(DVec3::new(0.0, 0.6, 0.8));
        let g = f.rotated_about_normal(0.9);
        let local = DVec3::new(0.5, 0.1, 0.86);
        assert!((f.to_world(local).dot(f.n) - g.to_world(local).dot(g.n)).abs() < 1e-12);
        let expected = f.to_world(DVec3::new(0.9f64.cos(), 0.9f64.sin(), 0.0));
        assert!((g.s - expected).length() < 1e-12);
    }
}
