//! Lambert's formula: the projected solid angle of a polygon, i.e. the
//! irradiance at a point from a polygon of unit uniform radiance.
//!
//! `∫_{Ω_P} cos θ dω = ½ |Σ_i Θ_i n·γ̂_i|`, with `u_i` the unit vectors from
//! the point to the vertices, `Θ_i = ∠(u_i, u_{i+1})` and
//! `γ̂_i = (u_i × u_{i+1}) / |u_i × u_{i+1}|` (J. H. Lambert, *Photometria*,
//! 1760; in modern form Arvo, "Applications of Irradiance Tensors to the
//! Simulation of Non-Lambertian Phenomena", SIGGRAPH 1995, eq. 6).
//!
//! This is the analytic reference the transport tests compare against; it
//! does not know about occlusion.

use glam::DVec3;

/// Projected solid angle (sr) of the planar polygon `vertices` seen from `x`
/// with unit normal `n`. The polygon is first clipped to the half-space
/// above the tangent plane, so parts behind the point do not count.
///
/// Vertices may be in either winding order. Irradiance from a polygon of
/// uniform radiance `L` facing `x` is `L` times this value (W/m²).
pub fn projected_solid_angle(x: DVec3, n: DVec3, vertices: &[DVec3]) -> f64 {
    let clipped = clip_above_plane(vertices.iter().map(|v| *v - x), n);
    if clipped.len() < 3 {
        return 0.0;
    }
    let dirs: Vec<DVec3> = clipped.iter().map(|p| p.normalize_or_zero()).collect();
    let mut sum = 0.0;
    for (i, &a) in dirs.iter().enumerate() {
        let b = dirs[(i + 1) % dirs.len()];
        let cross = a.cross(b);
        let len = cross.length();
        if len > 0.0 {
            let theta = len.atan2(a.dot(b));
            sum += theta * n.dot(cross / len);
        }
    }
    0.5 * sum.abs()
}

/// Sutherland–Hodgman clip of a polygon (vertices relative to the point)
/// against the half-space `n·p ≥ 0`.
fn clip_above_plane(points: impl Iterator<Item = DVec3>, n: DVec3) -> Vec<DVec3> {
    let points: Vec<DVec3> = points.collect();
    let mut out = Vec::with_capacity(points.len() + 1);
    for (i, &a) in points.iter().enumerate() {
        let b = points[(i + 1) % points.len()];
        let (da, db) = (n.dot(a), n.dot(b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out.push(a + (b - a) * t);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    /// Form factor from a differential area to a parallel rectangle `a × b`
    /// at height `h` whose corner is straight above it (Howell, *A Catalog
    /// of Radiation Heat Transfer Configuration Factors*, B-3).
    fn corner_form_factor(a: f64, b: f64, h: f64) -> f64 {
        let (x, y) = (a / h, b / h);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / TAU
    }

    #[test]
    fn parallel_rectangle_matches_the_form_factor_catalogue() {
        let (a, b, h) = (0.7, 1.9, 0.5);
        let rect = [
            DVec3::new(0.0, 0.0, h),
            DVec3::new(a, 0.0, h),
            DVec3::new(a, b, h),
            DVec3::new(0.0, b, h),
        ];
        let got = projected_solid_angle(DVec3::ZERO, DVec3::Z, &rect);
        let expected = PI * corner_form_factor(a, b, h);
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
        // Winding order does not matter.
        let mut reversed = rect;
        reversed.reverse();
        assert!((projected_solid_angle(DVec3::ZERO, DVec3::Z, &reversed) - got).abs() < 1e-15);
    }

    #[test]
    fn polygon_covering_the_hemisphere_gives_pi() {
        // A huge square just above the point covers almost the whole
        // hemisphere: ∫_H cos θ dω = π.
        let s = 1e7;
        let square = [
            DVec3::new(-s, -s, 1.0),
            DVec3::new(s, -s, 1.0),
            DVec3::new(s, s, 1.0),
            DVec3::new(-s, s, 1.0),
        ];
        assert!((projected_solid_angle(DVec3::ZERO, DVec3::Z, &square) - PI).abs() < 1e-6);
    }

    #[test]
    fn polygon_straddling_the_horizon_matches_quadrature() {
        // A vertical square in front of a tilted point: part of it is below
        // the tangent plane. Brute-force ∫ cos θ over the square by area:
        // dω cos θ = cos θ cos θ_l / r² dA.
        let n = DVec3::new(0.0, 0.3, 1.0).normalize();
        let x = DVec3::ZERO;
        let quad = [
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(1.0, 1.0, -1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
        ];
        let light_n = -DVec3::Y;
        let m = 1000;
        let mut sum = 0.0;
        for i in 0..m {
            for j in 0..m {
                let p = DVec3::new(
                    -1.0 + 2.0 * (i as f64 + 0.5) / m as f64,
                    1.0,
                    -1.0 + 2.0 * (j as f64 + 0.5) / m as f64,
                );
                let d = p - x;
                let r2 = d.length_squared();
                let w = d / r2.sqrt();
                sum += n.dot(w).max(0.0) * light_n.dot(-w) / r2;
            }
        }
        let expected = sum * 4.0 / (m * m) as f64;
        let got = projected_solid_angle(x, n, &quad);
        assert!((got - expected).abs() < 1e-5, "{got} vs {expected}");
        assert!(got > 0.0 && got < PI);
    }

    #[test]
    fn polygon_behind_the_point_gives_zero() {
        let tri = [
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(1.0, 0.0, -1.0),
            DVec3::new(0.0, 1.0, -1.0),
        ];
        assert_eq!(projected_solid_angle(DVec3::ZERO, DVec3::Z, &tri), 0.0);
    }
}
