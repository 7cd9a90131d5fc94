//! Bilinear interpolation of RGB grid values, shared by bitmap textures and
//! environment maps (each decides where its texels sit and how indices
//! wrap).

use glam::DVec2;

/// The blend of the four corner values `[v00, v10, v01, v11]` (x first)
/// at fractional position `t ∈ [0, 1]²` between them.
pub(crate) fn blend(corners: [[f64; 3]; 4], t: DVec2) -> [f64; 3] {
    let [a, b, c, d] = corners;
    std::array::from_fn(|k| {
        (1.0 - t.y) * ((1.0 - t.x) * a[k] + t.x * b[k]) + t.y * ((1.0 - t.x) * c[k] + t.x * d[k])
    })
}
