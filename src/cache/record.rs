//! Irradiance-cache records (Ward et al. 1988; docs/math.md §9): what one BMC
//! evaluation at a surface point contributes to its neighbourhood.

use glam::DVec3;

use super::error::{CacheError, positive};
use super::record_rule::RecordEstimate;
use crate::render::{QueryPoint, Rgb};
use crate::sphere::Frame;

/// Bounds of the validity radius, world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiusLimits {
    pub min: f64,
    pub max: f64,
}

impl RadiusLimits {
    /// Validated limits, `0 < min ≤ max < ∞`.
    pub fn new(min: f64, max: f64) -> Result<Self, CacheError> {
        positive("min_radius", min)?;
        positive("max_radius", max)?;
        if min > max {
            return Err(CacheError::invalid(
                "min_radius",
                format!("must not exceed max_radius {max}, got {min}"),
            ));
        }
        Ok(Self { min, max })
    }

    /// Tightened by a pixel footprint (the world size of one pixel at the
    /// point, from the caller's camera): radii between `min_pixels` and
    /// `max_pixels` footprints, never outside these limits (Tabellion &
    /// Lamorlette 2004 bound radii in screen space likewise).
    pub fn with_footprint(self, footprint: &PixelFootprint) -> Self {
        let min = (footprint.size * footprint.min_pixels).clamp(self.min, self.max);
        let max = (footprint.size * footprint.max_pixels).clamp(min, self.max);
        Self { min, max }
    }

    pub fn clamp(&self, radius: f64) -> f64 {
        radius.clamp(self.min, self.max)
    }
}

/// Radius bounds in pixels of a given world-space pixel size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelFootprint {
    /// World-space size of one pixel at the point.
    pub size: f64,
    pub min_pixels: f64,
    pub max_pixels: f64,
}

impl PixelFootprint {
    pub fn new(size: f64, min_pixels: f64, max_pixels: f64) -> Result<Self, CacheError> {
        positive("footprint", size)?;
        positive("min_pixels", min_pixels)?;
        positive("max_pixels", max_pixels)?;
        if min_pixels > max_pixels {
            return Err(CacheError::invalid(
                "min_pixels",
                format!("must not exceed max_pixels {max_pixels}, got {min_pixels}"),
            ));
        }
        Ok(Self {
            size,
            min_pixels,
            max_pixels,
        })
    }
}

/// Harmonic mean of the ray lengths, `N / Σ 1/r_i` (Ward et al. 1988), with
/// escaped rays (`r = ∞`) contributing `1/r = 0`; `None` when no ray hit.
/// Nearby geometry dominates, which is what limits how far `E` stays smooth.
pub fn harmonic_mean_distance(distances: &[f64]) -> Option<f64> {
    let inverse: f64 = distances
        .iter()
        .filter(|d| d.is_finite() && **d > 0.0)
        .map(|d| 1.0 / d)
        .sum();
    (inverse > 0.0).then(|| distances.len() as f64 / inverse)
}

/// Largest irradiance a record received from elsewhere may carry, W/m²
/// ([`Record::validate_received`]): far above any scene's (the sun gives
/// about 1e3), and small enough that what records are turned into (a few
/// weighted records with their gradient terms, variances as squares) stays
/// far inside the `f32` range (3.4e38) of the tiles' encodings.
pub const MAX_IRRADIANCE: f64 = 1e15;

/// One cached irradiance value with its uncertainty and validity region.
///
/// Invariants: `normal` is unit length, `radius > 0`, every value finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// World-space position `x_k`.
    pub position: DVec3,
    /// Unit world-space normal `n_k`.
    pub normal: DVec3,
    /// `E_k`, W/m².
    pub irradiance: Rgb,
    /// Posterior variance of `E_k`, (W/m²)² ([`RecordEstimate::variance`]).
    pub variance: Rgb,
    /// Validity radius `R_k`, world units.
    pub radius: f64,
    /// Per channel (r, g, b): world vector `g` with `E(n) ≈ E_k + g·(n_k × n)`
    /// (W/m² per radian; `n_k × n` is the rotation taking `n_k` to `n`).
    pub rotation_gradient: [DVec3; 3],
    /// Per channel: tangent world vector with `E(x) ≈ E_k + g·(x − x_k)` (W/m³).
    pub translation_gradient: [DVec3; 3],
}

impl Record {
    /// Bytes of [`Self::to_le_bytes`]: 31 little-endian `f64`s.
    pub const ENCODED_BYTES: usize = 31 * 8;

    /// The record as 31 little-endian `f64`s in field order (position,
    /// normal, irradiance, variance, radius, rotation then translation
    /// gradients, channel by channel): the stable form of the record log.
    pub fn to_le_bytes(&self) -> Vec<u8> {
        let mut values = Vec::with_capacity(31);
        values.extend(self.position.to_array());
        values.extend(self.normal.to_array());
        values.extend(self.irradiance.to_array());
        values.extend(self.variance.to_array());
        values.push(self.radius);
        for g in self
            .rotation_gradient
            .iter()
            .chain(&self.translation_gradient)
        {
            values.extend(g.to_array());
        }
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    /// The inverse of [`Self::to_le_bytes`], validated like an inserted
    /// record; `None` for a wrong length or an invalid record.
    pub fn from_le_bytes(bytes: &[u8]) -> Option<Record> {
        if bytes.len() != Self::ENCODED_BYTES {
            return None;
        }
        let v: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        let vec3 = |i: usize| DVec3::new(v[i], v[i + 1], v[i + 2]);
        let rgb = |i: usize| Rgb::new(v[i], v[i + 1], v[i + 2]);
        let record = Record {
            position: vec3(0),
            normal: vec3(3),
            irradiance: rgb(6),
            variance: rgb(9),
            radius: v[12],
            rotation_gradient: [vec3(13), vec3(16), vec3(19)],
            translation_gradient: [vec3(22), vec3(25), vec3(28)],
        };
        record.validate().ok().map(|()| record)
    }

    /// Validity radius of a record whose rays hit at `distances`: their
    /// harmonic mean distance clamped to `limits` (`limits.max` if no ray hit
    /// anything).
    pub fn radius_from(distances: &[f64], limits: RadiusLimits) -> f64 {
        limits.clamp(harmonic_mean_distance(distances).unwrap_or(limits.max))
    }

    /// The record [`Self::from_estimate`] would make at `point`, with zero
    /// irradiance, variance and gradients until its estimate is known
    /// (`IrradianceCache::insert_awaiting_values`).
    pub fn awaiting_values(point: &QueryPoint, distances: &[f64], limits: RadiusLimits) -> Record {
        Record {
            position: point.position(),
            normal: point.normal(),
            irradiance: Rgb::BLACK,
            variance: Rgb::BLACK,
            radius: Self::radius_from(distances, limits),
            rotation_gradient: [DVec3::ZERO; 3],
            translation_gradient: [DVec3::ZERO; 3],
        }
    }

    /// Record at `point` from a BMC estimate made in `frame` (the frame the
    /// rays were cast in: the point's normal, possibly turned about it).
    ///
    /// Radius: the harmonic mean distance of the rays clamped to `limits`
    /// (`limits.max` if no ray hit anything). Translation gradients are then
    /// clamped so that `|g_c| R ≤ E_c`: extrapolating to the edge of the
    /// validity sphere never changes a channel by more than its own value, the
    /// gradient limit of Křivánek et al. 2006 ("Making radiance and irradiance
    /// caching practical", §3.1), which keeps noisy gradients from producing
    /// negative or blotchy irradiance.
    pub fn from_estimate(
        point: &QueryPoint,
        frame: &Frame,
        estimate: &RecordEstimate,
        distances: &[f64],
        limits: RadiusLimits,
    ) -> Record {
        let radius = Self::radius_from(distances, limits);
        let world = |g: &[Rgb; 2]| -> [DVec3; 3] {
            let (x, y) = (g[0].to_array(), g[1].to_array());
            [0, 1, 2].map(|c| frame.s * x[c] + frame.t * y[c])
        };
        let mut translation_gradient = world(&estimate.translation);
        let e = estimate.irradiance.to_array();
        for (g, e) in translation_gradient.iter_mut().zip(e) {
            let reach = g.length() * radius;
            if reach > e.max(0.0) {
                *g *= e.max(0.0) / reach;
            }
        }
        Record {
            position: point.position(),
            normal: point.normal(),
            irradiance: estimate.irradiance,
            variance: estimate.variance,
            radius,
            rotation_gradient: world(&estimate.rotation),
            translation_gradient,
        }
    }

    /// Check the invariants (fields are public).
    pub fn validate(&self) -> Result<(), CacheError> {
        let finite3 = |v: &[DVec3; 3]| v.iter().all(|g| g.is_finite());
        let finite_rgb = |c: Rgb| c.to_array().iter().all(|v| v.is_finite());
        if !self.position.is_finite() {
            return Err(CacheError::invalid("position", "must be finite"));
        }
        if !self.normal.is_finite() || (self.normal.length() - 1.0).abs() > 1e-6 {
            return Err(CacheError::invalid(
                "normal",
                "must be a finite unit vector",
            ));
        }
        positive("radius", self.radius)?;
        if !finite_rgb(self.irradiance) || !finite_rgb(self.variance) {
            return Err(CacheError::invalid("irradiance", "must be finite"));
        }
        if !finite3(&self.rotation_gradient) || !finite3(&self.translation_gradient) {
            return Err(CacheError::invalid("gradient", "must be finite"));
        }
        Ok(())
    }

    /// Checks a record that did not come from this process's own
    /// computation (an import, another replica, the log on disk) as strictly
    /// as computed records hold: [`Self::validate`], irradiance and variance
    /// non-negative (the negative-weight guard, docs/math.md §3.6) and at most
    /// [`MAX_IRRADIANCE`] and its square, the radius within `limits`, the
    /// translation gradient within the clamp of [`Self::from_estimate`]
    /// (`|g_c| R ≤ E_c`) and the rotation gradient at most
    /// [`MAX_IRRADIANCE`] per radian.
    pub fn validate_received(&self, limits: RadiusLimits) -> Result<(), CacheError> {
        self.validate()?;
        let e = self.irradiance.to_array();
        if e.iter().any(|&v| !(0.0..=MAX_IRRADIANCE).contains(&v)) {
            return Err(CacheError::invalid(
                "irradiance",
                format!("must be within [0, {MAX_IRRADIANCE:e}] W/m², got {e:?}"),
            ));
        }
        let max_variance = MAX_IRRADIANCE * MAX_IRRADIANCE;
        let variance = self.variance.to_array();
        if variance.iter().any(|&v| !(0.0..=max_variance).contains(&v)) {
            return Err(CacheError::invalid(
                "variance",
                format!("must be within [0, {max_variance:e}] (W/m²)², got {variance:?}"),
            ));
        }
        // The limits are checked as computed records meet them, not clamped.
        if self.radius < limits.min * (1.0 - 1e-12) || self.radius > limits.max * (1.0 + 1e-12) {
            return Err(CacheError::invalid(
                "radius",
                format!(
                    "must be within [{}, {}], got {}",
                    limits.min, limits.max, self.radius
                ),
            ));
        }
        for (c, g) in self.translation_gradient.iter().enumerate() {
            // Rounding of the clamp's rescaling only.
            if g.length() * self.radius > e[c] * (1.0 + 1e-9) + f64::MIN_POSITIVE {
                return Err(CacheError::invalid(
                    "translation_gradient",
                    "must change irradiance by at most its own value within the radius",
                ));
            }
        }
        if self
            .rotation_gradient
            .iter()
            .any(|g| g.length() > MAX_IRRADIANCE)
        {
            return Err(CacheError::invalid(
                "rotation_gradient",
                format!("must be at most {MAX_IRRADIANCE:e} W/m² per radian"),
            ));
        }
        Ok(())
    }

    /// Ward's weight `w_k(x) = 1/(|x − x_k|/R_k + sqrt(1 − n·n_k))`
    /// (docs/math.md §9); infinite at the record itself.
    pub fn weight(&self, x: DVec3, n: DVec3) -> f64 {
        let denominator =
            (x - self.position).length() / self.radius + (1.0 - n.dot(self.normal)).max(0.0).sqrt();
        1.0 / denominator
    }

    /// Ward's "in front" distance `d_k = (x − x_k)·(n + n_k)/2` (Ward et al.
    /// 1988): negative when `x` lies behind the record's tangent plane (the
    /// record sits in front of `x`), whose hemisphere then sees geometry `x`
    /// cannot.
    pub fn front_distance(&self, x: DVec3, n: DVec3) -> f64 {
        (x - self.position).dot(0.5 * (n + self.normal))
    }

    /// `E_k` extrapolated to `(x, n)` with both gradients, clamped at 0 per
    /// channel. Only the tangent part of `x − x_k` enters, as the gradient
    /// is tangent.
    pub fn extrapolate(&self, x: DVec3, n: DVec3) -> Rgb {
        let turn = self.normal.cross(n);
        let shift = x - self.position;
        let e = self.irradiance.to_array();
        Rgb::from_array([0, 1, 2].map(|c| {
            (e[c] + self.rotation_gradient[c].dot(turn) + self.translation_gradient[c].dot(shift))
                .max(0.0)
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    mod received {
        use super::*;
        use crate::cache::{Accuracy, CacheConfig, IrradianceCache};
        use proptest::prelude::*;

        /// Values as a forger picks them: ordinary ones, and the edges of f64.
        fn wild() -> impl Strategy<Value = f64> {
            prop_oneof![
                4 => -2.0..2.0f64,
                1 => prop::sample::select(vec![
                    0.0, -0.0, 1e-300, -1e4, 1e14, 1e15, 1e16, 1e300, -1e300,
                    f64::MAX, f64::MIN, f64::INFINITY, f64::NEG_INFINITY, f64::NAN,
                ]),
                1 => any::<f64>(),
            ]
        }

        fn received_record() -> impl Strategy<Value = Record> {
            (
                prop::array::uniform3(-1.0..1.0f64),
                prop::array::uniform3(wild()),
                prop::array::uniform3(wild()),
                wild(),
                prop::array::uniform9(wild()),
                prop::array::uniform9(wild()),
                prop::array::uniform3(-1.0..1.0f64),
            )
                .prop_map(|(p, e, v, radius, rot, trans, n)| {
                    let n = DVec3::from_array(n);
                    let g = |a: [f64; 9]| {
                        [0, 1, 2].map(|c| DVec3::new(a[3 * c], a[3 * c + 1], a[3 * c + 2]))
                    };
                    Record {
                        position: DVec3::from_array(p),
                        normal: if n.length() > 1e-3 {
                            n.normalize()
                        } else {
                            DVec3::Z
                        },
                        irradiance: Rgb::from_array(e),
                        variance: Rgb::from_array(v),
                        radius: radius.abs(),
                        rotation_gradient: g(rot),
                        translation_gradient: g(trans),
                    }
                })
        }

        proptest! {
            #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]
            /// Whatever records are received, those accepted never make a
            /// lookup non-finite, nor too large for the tiles' `f32`s.
            #[test]
            fn accepted_records_give_finite_lookups(
                records in prop::collection::vec(received_record(), 1..24),
                points in prop::collection::vec(
                    (prop::array::uniform3(-1.0..1.0f64), prop::array::uniform3(-1.0..1.0f64)), 1..16),
            ) {
                let config = CacheConfig::default();
                let limits = config.validate().unwrap();
                let cache = IrradianceCache::new(config).unwrap();
                for r in &records {
                    if r.validate_received(limits).is_ok() {
                        cache.insert(*r).unwrap();
                    }
                }
                for (x, n) in points {
                    let n = DVec3::from_array(n);
                    let Ok(point) = QueryPoint::new(DVec3::from_array(x), if n.length() > 1e-3 { n.normalize() } else { DVec3::Z }) else {
                        continue;
                    };
                    if let Some(found) = cache.lookup(&point, Accuracy::new(1.0).unwrap()) {
                        for v in found.irradiance.to_array().into_iter().chain(found.variance.to_array()) {
                            prop_assert!((v as f32).is_finite() && v >= 0.0, "{found:?}");
                        }
                    }
                }
            }
        }

        #[test]
        fn poisoned_records_are_refused() {
            let limits = CacheConfig::default().validate().unwrap();
            let good = record();
            assert!(good.validate_received(limits).is_ok());
            let e = |v: f64| Rgb::new(v, 2.0, 3.0);
            for (bad, field) in [
                (
                    Record {
                        irradiance: e(1e300),
                        ..good
                    },
                    "irradiance",
                ),
                (
                    Record {
                        irradiance: e(-1e4),
                        ..good
                    },
                    "irradiance",
                ),
                (
                    Record {
                        variance: Rgb::new(-1.0, 0.0, 0.0),
                        ..good
                    },
                    "variance",
                ),
                (
                    Record {
                        radius: 1e9,
                        ..good
                    },
                    "radius",
                ),
                (
                    Record {
                        radius: 1e-9,
                        ..good
                    },
                    "radius",
                ),
                (
                    Record {
                        translation_gradient: [DVec3::X * 100.0, DVec3::ZERO, DVec3::ZERO],
                        ..good
                    },
                    "translation_gradient",
                ),
                (
                    Record {
                        rotation_gradient: [DVec3::X * 1e20, DVec3::ZERO, DVec3::ZERO],
                        ..good
                    },
                    "rotation_gradient",
                ),
                (
                    Record {
                        irradiance: e(f64::NAN),
                        ..good
                    },
                    "irradiance",
                ),
            ] {
                let err = bad.validate_received(limits).unwrap_err();
                assert_eq!(err.field(), Some(field), "{err}");
            }
        }
    }

    fn record() -> Record {
        Record {
            position: DVec3::new(1.0, 0.0, 0.0),
            normal: DVec3::Z,
            irradiance: Rgb::new(1.0, 2.0, 3.0),
            variance: Rgb::splat(0.01),
            radius: 0.5,
            rotation_gradient: [DVec3::new(0.5, 0.0, 0.0), DVec3::ZERO, DVec3::ZERO],
            translation_gradient: [DVec3::ZERO, DVec3::new(0.0, 1.0, 0.0), DVec3::ZERO],
        }
    }

    #[test]
    fn the_log_form_round_trips_bit_for_bit() {
        let mut r = record();
        r.rotation_gradient[1] = DVec3::new(0.25, -1.5e-7, 3.0);
        r.translation_gradient[2] = DVec3::new(f64::MIN_POSITIVE, 0.0, -2.0);
        let bytes = r.to_le_bytes();
        assert_eq!(bytes.len(), Record::ENCODED_BYTES);
        assert_eq!(Record::from_le_bytes(&bytes), Some(r));
        assert_eq!(Record::from_le_bytes(&bytes[1..]), None);
        // A record that would not be inserted is not read back either.
        let mut bad = r;
        bad.radius = -1.0;
        assert_eq!(Record::from_le_bytes(&bad.to_le_bytes()), None);
    }

    #[test]
    fn harmonic_mean_ignores_escaped_rays_in_the_sum() {
        let d = harmonic_mean_distance(&[1.0, 2.0, f64::INFINITY, 4.0]).unwrap();
        assert!((d - 4.0 / 1.75).abs() < 1e-12);
        assert_eq!(harmonic_mean_distance(&[f64::INFINITY]), None);
    }

    #[test]
    fn limits_and_footprint_clamp_radii() {
        let l = RadiusLimits::new(0.01, 1.0).unwrap();
        assert_eq!(l.clamp(5.0), 1.0);
        assert_eq!(l.clamp(0.0), 0.01);
        let fp = PixelFootprint::new(0.004, 5.0, 50.0).unwrap();
        let t = l.with_footprint(&fp);
        assert!((t.min - 0.02).abs() < 1e-15 && (t.max - 0.2).abs() < 1e-15);
        assert_eq!(
            RadiusLimits::new(2.0, 1.0).unwrap_err().field(),
            Some("min_radius")
        );
        assert_eq!(
            RadiusLimits::new(f64::NAN, 1.0).unwrap_err().field(),
            Some("min_radius")
        );
        assert_eq!(
            PixelFootprint::new(-1.0, 1.0, 2.0).unwrap_err().field(),
            Some("footprint")
        );
    }

    #[test]
    fn weight_and_extrapolation() {
        let r = record();
        assert!(r.weight(r.position, r.normal).is_infinite());
        assert!((r.weight(r.position + DVec3::X * 0.25, DVec3::Z) - 2.0).abs() < 1e-12);
        assert_eq!(r.extrapolate(r.position, r.normal), r.irradiance);
        // Tilt the normal towards +y by a small angle: n_k × n ≈ (−ε, 0, 0).
        let eps: f64 = 1e-3;
        let n = DVec3::new(0.0, eps.sin(), eps.cos());
        let e = r.extrapolate(r.position, n);
        assert!((e.r - (1.0 - 0.5 * eps)).abs() < 1e-9);
        let e = r.extrapolate(r.position + DVec3::new(0.0, 0.1, 0.0), DVec3::Z);
        assert!((e.g - 2.1).abs() < 1e-12);
        // Behind the tangent plane → negative front distance.
        assert!(r.front_distance(r.position - DVec3::Z * 0.1, DVec3::Z) < 0.0);
        assert!(r.validate().is_ok());
        let mut bad = r;
        bad.radius = 0.0;
        assert_eq!(bad.validate().unwrap_err().field(), Some("radius"));
    }

    /// A record of the linear field `L = a + b·ω` (world) extrapolated to a
    /// tilted normal tracks `E(n) = aπ + (2π/3) b·n` (docs/math.md §8) far
    /// better than the record's own value does (to first order).
    #[test]
    fn rotation_gradient_tracks_a_tilted_normal() {
        use crate::bmc::{Kernel, KernelKind, PriorMean};
        use crate::cache::record_rule::{RecordRule, RecordRuleSpec};
        use crate::render::RadianceSample;
        use crate::sphere::{SampleSetKind, SampleSetSpec};
        let rule = RecordRule::new(RecordRuleSpec {
            samples: SampleSetSpec {
                kind: SampleSetKind::Fibonacci,
                count: 64,
                seed: 0,
            },
            kernel: Kernel::new(KernelKind::SquaredExponential, 1.0, 1.0, 1e-8).unwrap(),
            prior_mean: PriorMean::Gls,
        })
        .unwrap();
        let (a, b) = (1.0, DVec3::new(0.4, 0.2, -0.3));
        let truth =
            |n: DVec3| a * std::f64::consts::PI + 2.0 * std::f64::consts::PI / 3.0 * b.dot(n);
        let normal = DVec3::new(0.2, 0.3, 1.0).normalize();
        let frame = Frame::from_normal(normal).rotated_about_normal(0.7);
        let samples: Vec<RadianceSample> = rule
            .directions()
            .iter()
            .map(|d| RadianceSample {
                radiance: Rgb::splat(a + b.dot(frame.to_world(*d))),
                distance: f64::INFINITY,
                variance: Rgb::BLACK,
                direct: Rgb::BLACK,
            })
            .collect();
        let estimate = rule.estimate(&samples).unwrap();
        let p = QueryPoint::new(DVec3::ZERO, normal).unwrap();
        let r = Record::from_estimate(
            &p,
            &frame,
            &estimate,
            &[],
            RadiusLimits::new(0.1, 1.0).unwrap(),
        );
        assert!((r.irradiance.r - truth(normal)).abs() < 1e-6);
        let errors = |s: f64| {
            let tilted = (normal + s * DVec3::new(0.15, -0.1, 0.0)).normalize();
            let with = (r.extrapolate(DVec3::ZERO, tilted).r - truth(tilted)).abs();
            (with, (r.irradiance.r - truth(tilted)).abs())
        };
        let (with, without) = errors(1.0);
        assert!(with < 0.1 * without, "{with} vs {without}");
        // The remaining error is second order in the tilt.
        let (half, _) = errors(0.5);
        assert!(half < 0.3 * with, "{half} vs {with}");
    }

    #[test]
    fn translation_gradient_is_clamped_to_the_radius() {
        let estimate = RecordEstimate {
            irradiance: Rgb::splat(1.0),
            variance: Rgb::BLACK,
            rotation: [Rgb::BLACK; 2],
            translation: [Rgb::splat(10.0), Rgb::BLACK],
        };
        let p = QueryPoint::new(DVec3::ZERO, DVec3::Z).unwrap();
        let frame = Frame::from_normal(DVec3::Z);
        let r = Record::from_estimate(
            &p,
            &frame,
            &estimate,
            &[1.0, 1.0],
            RadiusLimits::new(0.1, 0.5).unwrap(),
        );
        assert_eq!(r.radius, 0.5);
        for g in r.translation_gradient {
            assert!((g.length() * r.radius - 1.0).abs() < 1e-12);
        }
    }
}
