//! Shadow probes (docs/math.md §10.8): a few samples of the direct light
//! drawn from the same fixed numbers at every point. Two points nearby then
//! sample the same parts of the lights (the same directions of an
//! environment, the same places on an emitter) and directions turned alike
//! with their normals, so the difference of their probes is what the
//! occluders and the normals between them change in their direct light,
//! with none of the noise two independent estimates would add.

use glam::DVec3;
use rand::SeedableRng;

use super::path::TraceStats;
use super::query::QueryPoint;
use super::transport::Transport;
use crate::color::Rgb;

/// Samples per probe (each a light sample, and a cosine direction where an
/// environment shines, as [`Transport::direct_irradiance`] draws them).
pub const SHADOW_PROBES: u32 = 4;

/// The seed of every probe's numbers.
const PROBE_SEED: u64 = 0x5AD0_0B5E;

impl Transport {
    /// The probe at `point`: [`Transport::direct_irradiance`]'s mean of
    /// [`SHADOW_PROBES`] samples (W/m²) from numbers every point shares, an
    /// unbiased estimate of the direct irradiance, and its gradient with
    /// respect to the normal from the same samples
    /// ([`Transport::direct_irradiance_and_normal_gradient`]); its rays
    /// are counted in `stats`.
    pub fn shadow_probe(&self, point: &QueryPoint, stats: &mut TraceStats) -> (Rgb, [DVec3; 3]) {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(PROBE_SEED);
        let (probe, gradient) =
            self.direct_irradiance_and_normal_gradient(point, SHADOW_PROBES, &mut rng, stats);
        (probe.mean, gradient)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probes_see_shadows_and_repeat_exactly() {
        let transport = crate::testing::occluded_ground(0.0);
        let at = |x: f64| QueryPoint::new(DVec3::new(x, 0.0, 0.0), DVec3::Z).unwrap();
        let mut stats = TraceStats::default();
        // Under the occluder: the light is hidden.
        assert_eq!(transport.shadow_probe(&at(0.1), &mut stats).0, Rgb::BLACK);
        // Beside it: the point light's irradiance I cos θ / r², exactly.
        let (lit, gradient) = transport.shadow_probe(&at(1.0), &mut stats);
        let (r2, cos) = (5.0, 2.0 / 5f64.sqrt());
        assert!((lit.r - 4.0 * cos / r2).abs() < 1e-12, "{lit:?}");
        assert_eq!(transport.shadow_probe(&at(1.0), &mut stats).0, lit);
        // ∂E/∂n = I ω / r², towards the light.
        let towards = DVec3::new(-1.0, 0.0, 2.0) / r2.sqrt();
        assert!(
            (gradient[0] - towards * (4.0 / r2)).length() < 1e-12,
            "{gradient:?}"
        );
        assert_eq!(stats.rays, 3 * u64::from(SHADOW_PROBES));
    }
}
