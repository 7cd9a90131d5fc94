//! Irradiance meters: Mitsuba 3's `irradiancemeter`, a sensor on a shape
//! that measures the mean irradiance over the shape's front side (W/m²).
//! Here a meter is a point query (docs/math.md §10.12): the irradiance is
//! estimated at the centres of a stratified grid of points on the shape,
//! with the shape's front normals, and averaged.

use glam::DVec3;

use super::Scene;

/// An irradiance meter of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct IrradianceMeter {
    /// The shape's `id`, or its field path (`shapes[3]`) without one.
    pub id: String,
    /// The shape it measures over: an index into the scene's shapes.
    pub shape: usize,
}

/// Points per side of the grid a meter is measured at.
pub const METER_GRID: usize = 4;

impl Scene {
    /// The points a meter is measured at, (position, front normal): the
    /// images of the centres of a [`METER_GRID`]² grid of the unit square
    /// under the shape's area sampling, each standing for an equal share
    /// of its area.
    pub fn meter_points(&self, meter: &IrradianceMeter) -> Vec<(DVec3, DVec3)> {
        let n = METER_GRID as f64;
        (0..METER_GRID * METER_GRID)
            .map(|k| {
                let u = [
                    ((k % METER_GRID) as f64 + 0.5) / n,
                    ((k / METER_GRID) as f64 + 0.5) / n,
                ];
                let (p, normal, _) = self.sample_shape_area(meter.shape, u);
                (p, normal)
            })
            .collect()
    }
}

/// A meter's value from the estimates at its points, per channel: their
/// mean, and the standard error of a mean of K independent estimates,
/// `√(max(s², mean σᵢ²) / K)`: `s²`, the spread of the K estimates over the
/// shape, holds both their own errors and the irradiance's variation
/// across the shape; it is never taken below the points' own mean
/// variance `σᵢ²` (docs/math.md §10.12).
pub fn meter_value(values: &[[f64; 3]], std_dev: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let k = values.len().max(1) as f64;
    let mut mean = [0.0; 3];
    let mut error = [0.0; 3];
    for c in 0..3 {
        mean[c] = values.iter().map(|v| v[c]).sum::<f64>() / k;
        let spread =
            values.iter().map(|v| (v[c] - mean[c]).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
        let own = std_dev.iter().map(|s| s[c] * s[c]).sum::<f64>() / k;
        error[c] = (spread.max(own) / k).sqrt();
    }
    (mean, error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_meters_value_is_the_mean_with_both_errors() {
        let (mean, error) = meter_value(&[[1.0; 3], [3.0; 3]], &[[0.1; 3], [0.3; 3]]);
        assert_eq!(mean, [2.0; 3]);
        // s² = 2 over mean σ² = 0.05: √(2 / 2).
        assert!((error[0] - 1.0).abs() < 1e-12);
        // Equal estimates: the points' own errors, averaged.
        let (_, error) = meter_value(&[[1.0; 3], [1.0; 3]], &[[0.1; 3], [0.3; 3]]);
        assert!((error[0] - (0.05f64 / 2.0).sqrt()).abs() < 1e-12);
    }
}
