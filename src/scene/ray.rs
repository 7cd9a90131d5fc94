//! Rays and the offsets that keep secondary rays from re-hitting the surface
//! they leave.

use glam::DVec3;

/// A ray `origin + t·dir` for `0 < t < t_max`; `dir` is unit length (world
/// units, so `t` is a distance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: DVec3,
    pub dir: DVec3,
    pub t_max: f64,
}

impl Ray {
    /// Point at distance `t` along the ray.
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }
}

/// Relative size of the self-intersection offset.
///
/// Hit points are reconstructed on the surface in f64 (barycentric
/// interpolation for triangles, reprojection for spheres and disks), so their
/// error is a few ulps of the coordinate magnitude (~1e-15 relative). The
/// offset follows the idea of Wächter & Binder, "A Fast and Robust Method for
/// Avoiding Self-Intersection" (Ray Tracing Gems, 2019): move the origin along
/// the geometric normal by an amount that scales with the coordinates' own
/// magnitude, plus an absolute floor near the world origin. 2⁻³² relative is
/// ~10⁶ ulps above the error and still far thinner than any modelled wall.
const OFFSET_RELATIVE: f64 = 1.0 / 4_294_967_296.0;
/// Absolute offset floor for points near the world origin.
const OFFSET_ABSOLUTE: f64 = 1e-9;

/// `position` moved off its surface along `normal`, to the side `toward` points to.
#[inline]
pub fn offset_origin(position: DVec3, normal: DVec3, toward: DVec3) -> DVec3 {
    let n = if normal.dot(toward) < 0.0 {
        -normal
    } else {
        normal
    };
    let magnitude = position.abs().max_element();
    position + n * (OFFSET_ABSOLUTE + OFFSET_RELATIVE * magnitude)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_to_the_side_of_the_direction() {
        let p = DVec3::new(3.0, -2.0, 1.0);
        let n = DVec3::Y;
        assert!(offset_origin(p, n, DVec3::new(0.3, 1.0, 0.0)).y > p.y);
        assert!(offset_origin(p, n, DVec3::new(0.3, -1.0, 0.0)).y < p.y);
        // Grows with the coordinates so it stays above their rounding error.
        let far = DVec3::splat(1e6);
        let moved = offset_origin(far, n, n) - far;
        assert!(moved.y > far.y * f64::EPSILON * 1e3);
    }
}
