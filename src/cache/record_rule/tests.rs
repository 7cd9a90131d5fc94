use super::*;
use crate::sphere::SampleSetKind;

fn rule(kind: KernelKind, lengthscale: f64, count: usize) -> RecordRule {
    let kernel = Kernel::new(kind, lengthscale, 1.0, 1e-8).unwrap();
    rule_on(SampleSetKind::Fibonacci, kernel, count)
}

/// The GLS rule on `count` directions of a set of `kind`.
fn rule_on(kind: SampleSetKind, kernel: Kernel, count: usize) -> RecordRule {
    RecordRule::new(RecordRuleSpec {
        samples: SampleSetSpec {
            kind,
            count,
            seed: 0,
        },
        kernel,
        prior_mean: PriorMean::Gls,
    })
    .unwrap()
}

/// One record's estimate with its speeds given.
fn with_speeds(r: &RecordRule, samples: &[RadianceSample], speeds: &[f64]) -> RecordEstimate {
    let mut one = r.estimate_with_speeds(&[(samples, speeds)]);
    one.pop().unwrap().unwrap()
}

/// A batch gives each record what it gets alone, in order, whatever
/// else the batch holds: records with the BMC rule, one with the wrong
/// number of samples (its own error) and one that falls back to the
/// equal-weight rule.
#[test]
fn a_batch_estimates_each_record_as_alone() {
    let kernel = Kernel::new(KernelKind::Matern32, 0.4, 1.0, 1e-6).unwrap();
    let r = rule_on(SampleSetKind::Stratified, kernel, 64);
    let dirs = r.directions().to_vec();
    let record = |phase: f64| -> Vec<RadianceSample> {
        dirs.iter()
            .map(|d| RadianceSample {
                radiance: Rgb::new(
                    1.0 + (3.0 * d.x + phase).sin().abs(),
                    0.5 + d.z,
                    0.2 + (d.y * phase).cos().powi(2),
                ),
                distance: 1.0 + (d.x + phase).abs(),
                variance: Rgb::splat(1e-3 * phase),
                direct: Rgb::BLACK,
            })
            .collect()
    };
    // A lit patch seen through the most negatively weighted ray.
    let w = &r.quadrature().weights;
    let k = (0..w.len()).min_by(|a, b| w[*a].total_cmp(&w[*b])).unwrap();
    let mut spiked = vec![RadianceSample::NONE; dirs.len()];
    spiked[k].radiance = Rgb::splat(100.0);
    spiked[k].distance = 1.0;
    let records = [record(0.3), record(1.7), spiked, record(2.9)];
    let mut batch: Vec<&[RadianceSample]> = records.iter().map(Vec::as_slice).collect();
    batch.insert(2, &records[0][..10]);
    let together = r.estimate_batch(&batch);
    assert_eq!(together.len(), 5);
    assert_eq!(together[2].as_ref().unwrap_err().field(), Some("samples"));
    let fallback = together[3].as_ref().unwrap();
    assert_eq!(fallback.rotation, [Rgb::BLACK; 2], "the equal-weight rule");
    for (i, got) in together.iter().enumerate().filter(|(i, _)| *i != 2) {
        let got = got.as_ref().unwrap();
        let alone = r.estimate(batch[i]).unwrap();
        let values = |e: &RecordEstimate| {
            let mut v = vec![e.irradiance, e.variance];
            v.extend(e.rotation);
            v.extend(e.translation);
            v.into_iter().flat_map(Rgb::to_array).collect::<Vec<f64>>()
        };
        for (a, b) in values(got).iter().zip(values(&alone)) {
            assert!(
                (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                "record {i}: {a} vs {b}"
            );
        }
        assert!(values(got).iter().any(|v| *v != 0.0));
    }
    assert_ne!(together[0].as_ref().unwrap().translation, [Rgb::BLACK; 2]);
}

/// A stratified set has negative Lambert weights (a Fibonacci set has
/// none); a lit patch seen through the most negatively weighted ray
/// makes `π Σ w_i L_i` negative, and the record takes the equal-weight
/// rule on the same rays (docs/math.md §3.6): `E = π (1/N) Σ 2 cos θ_i
/// L_i` for uniform-area directions, its sample variance, no gradients.
/// Without the spike the BMC record is unchanged.
#[test]
fn a_negative_record_falls_back_to_the_equal_weight_rule() {
    let kernel = Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 1e-8).unwrap();
    let r = rule_on(SampleSetKind::Stratified, kernel, 64);
    let w = &r.quadrature().weights;
    let (k, &most_negative) = w
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    assert!(most_negative < 0.0);
    let dirs = r.directions();
    let field = |d: &DVec3| Rgb::new(1.0 + 0.5 * d.x, 0.8, 0.6 + 0.3 * d.z);
    let mut samples: Vec<RadianceSample> = dirs
        .iter()
        .map(|d| RadianceSample {
            radiance: field(d),
            distance: 2.0,
            variance: Rgb::BLACK,
            direct: Rgb::BLACK,
        })
        .collect();
    let smooth = r.estimate(&samples).unwrap();
    let bmc = samples
        .iter()
        .zip(w)
        .map(|(s, w)| s.radiance * *w)
        .sum::<Rgb>()
        * PI;
    assert!((smooth.irradiance.r - bmc.r).abs() < 1e-12, "{smooth:?}");
    assert!(smooth.rotation[1].r != 0.0);
    samples[k].radiance = Rgb::new(40.0, 40.0, 40.0);
    let spiked_bmc = samples
        .iter()
        .zip(w)
        .map(|(s, w)| s.radiance * *w)
        .sum::<Rgb>();
    assert!(spiked_bmc.r < 0.0, "{spiked_bmc:?}");
    let e = r.estimate(&samples).unwrap();
    let terms: Vec<f64> = samples
        .iter()
        .zip(dirs)
        .map(|(s, d)| 2.0 * d.z * s.radiance.r)
        .collect();
    let n = terms.len() as f64;
    let mean = terms.iter().sum::<f64>() / n;
    let spread = terms.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / (n - 1.0);
    assert!((e.irradiance.r - PI * mean).abs() < 1e-9, "{e:?}");
    assert!((e.variance.r - PI * PI * spread / n).abs() < 1e-9, "{e:?}");
    assert!(e.irradiance.g > 0.0 && e.irradiance.b > 0.0);
    assert_eq!(e.rotation, [Rgb::BLACK; 2]);
    assert_eq!(e.translation, [Rgb::BLACK; 2]);
}

#[test]
fn kernel_slope_matches_finite_differences() {
    for kind in [
        KernelKind::SquaredExponential,
        KernelKind::Matern32,
        KernelKind::Matern52,
    ] {
        let k = Kernel::new(kind, 0.7, 1.3, 0.0).unwrap();
        for c in [-0.5, 0.1, 0.6, 0.95] {
            let h = 1e-6;
            let chord = |c: f64| (2.0 - 2.0 * c).sqrt();
            let fd = (k.eval_chord(chord(c + h)) - k.eval_chord(chord(c - h))) / (2.0 * h);
            let analytic = kernel_slope(&k, chord(c));
            assert!(
                (fd - analytic).abs() < 1e-6 * analytic.abs().max(1.0),
                "{kind:?} {c}"
            );
        }
    }
}

/// `∫_H (a + b·ω) cos θ dω = aπ + (2π/3) b·n` (docs/math.md §8), so turning
/// the normal about local x changes `E` at rate `−(2π/3) b_y`, about y at `(2π/3) b_x`.
#[test]
fn rotation_gradient_of_a_linear_field_is_exact() {
    let r = rule(KernelKind::SquaredExponential, 1.0, 64);
    let (a, b) = (0.8, DVec3::new(0.3, -0.5, 0.6));
    let samples: Vec<RadianceSample> = r
        .directions()
        .iter()
        .map(|d| RadianceSample {
            radiance: Rgb::new(a + b.dot(*d), a, 0.0),
            distance: f64::INFINITY,
            variance: Rgb::BLACK,
            direct: Rgb::BLACK,
        })
        .collect();
    let e = r.estimate(&samples).unwrap();
    let k = 2.0 * PI / 3.0;
    assert!(
        (e.rotation[0].r - (-k * b.y)).abs() < 1e-4,
        "{:?}",
        e.rotation
    );
    assert!((e.rotation[1].r - k * b.x).abs() < 1e-4, "{:?}", e.rotation);
    // A constant field has no gradient, and escaped rays no translation gradient.
    assert!(e.rotation[0].g.abs() < 1e-9 && e.rotation[1].g.abs() < 1e-9);
    assert_eq!(e.translation[0].r, 0.0);
    assert!((e.irradiance.g - PI * a).abs() < 1e-9);
}

/// BMC estimate `π wᵀY` recomputed from scratch for moved directions.
fn recomputed(r: &RecordRule, dirs: Vec<DVec3>, values: &[f64]) -> f64 {
    let set = SampleSet {
        spec: r.spec.samples,
        directions: dirs,
    };
    let f = Factorisation::new(&set, &r.spec.kernel).unwrap();
    let q = Quadrature::new(
        &set,
        &r.spec.kernel,
        &f,
        &Density::Lambert,
        r.spec.prior_mean,
        KernelMeanMethod::Exact,
    )
    .unwrap();
    PI * q.estimate(values)
}

/// Gradients against central differences of recomputed estimates: a
/// diffuse emitting plane at height 1 with spatially varying radiance.
#[test]
fn gradients_match_recomputed_estimates() {
    for kind in [KernelKind::SquaredExponential, KernelKind::Matern52] {
        let r = rule(kind, 0.6, 48);
        let radiance = |y: DVec3| 1.0 + 0.5 * (1.3 * y.x).sin() + 0.3 * (0.8 * y.y).cos();
        let hits: Vec<DVec3> = r.directions().iter().map(|d| *d / d.z).collect();
        let values: Vec<f64> = hits.iter().map(|y| radiance(*y)).collect();
        let samples: Vec<RadianceSample> = hits
            .iter()
            .zip(&values)
            .map(|(y, v)| RadianceSample {
                radiance: Rgb::splat(*v),
                distance: y.length(),
                variance: Rgb::BLACK,
                direct: Rgb::BLACK,
            })
            .collect();
        // The exact derivative moves each sample with its own 1/r.
        let speeds: Vec<f64> = hits.iter().map(|y| 1.0 / y.length()).collect();
        let e = with_speeds(&r, &samples, &speeds);
        let eps = 1e-5;
        for (axis, e_axis) in [(DVec3::X, 0), (DVec3::Y, 1)] {
            let moved = |s: f64| -> Vec<DVec3> {
                hits.iter().map(|y| (*y - s * axis).normalize()).collect()
            };
            let fd = (recomputed(&r, moved(eps), &values) - recomputed(&r, moved(-eps), &values))
                / (2.0 * eps);
            let g = e.translation[e_axis].r;
            assert!(
                (g - fd).abs() < 1e-4 * fd.abs().max(1.0),
                "{kind:?} t{e_axis}: {g} vs {fd}"
            );
            // Rotating the normal by +ε = rotating the samples by −ε.
            let turned = |s: f64| -> Vec<DVec3> {
                let q = glam::DQuat::from_axis_angle(axis, -s);
                r.directions().iter().map(|d| q * *d).collect()
            };
            let fd = (recomputed(&r, turned(eps), &values) - recomputed(&r, turned(-eps), &values))
                / (2.0 * eps);
            let g = e.rotation[e_axis].r;
            assert!(
                (g - fd).abs() < 1e-4 * fd.abs().max(1.0),
                "{kind:?} r{e_axis}: {g} vs {fd}"
            );
        }
    }
}

/// An occluding edge: a black half-plane `z = h, x < 0` in front of a
/// bright plane `z = 3` (radiance 1), seen from the origin (normal z).
/// The bright part is the cut hemisphere `ω_x ≥ −ω_z p_x/h`, so
/// `E(p_x) = (π/2)(1 + sin β)` with `tan β = p_x/h` and
/// `dE/dx = π/(2h)` at the origin: the edge moves with the occluder.
#[test]
fn occluding_edges_move_with_the_occluder() {
    let r = rule(KernelKind::SquaredExponential, 0.5, 256);
    let h = 0.3;
    let samples: Vec<RadianceSample> = r
        .directions()
        .iter()
        .map(|d| {
            let to_occluder = h / d.z;
            if to_occluder * d.x < 0.0 {
                RadianceSample {
                    radiance: Rgb::BLACK,
                    distance: to_occluder,
                    variance: Rgb::BLACK,
                    direct: Rgb::BLACK,
                }
            } else {
                RadianceSample {
                    radiance: Rgb::WHITE,
                    distance: 3.0 / d.z,
                    variance: Rgb::BLACK,
                    direct: Rgb::BLACK,
                }
            }
        })
        .collect();
    let exact = PI / (2.0 * h);
    let e = r.estimate(&samples).unwrap();
    assert!(
        (e.irradiance.r - PI / 2.0).abs() < 0.02 * PI,
        "{:?}",
        e.irradiance
    );
    let edges = e.translation[0].r;
    let own: Vec<f64> = samples.iter().map(|s| 1.0 / s.distance).collect();
    let plain = with_speeds(&r, &samples, &own).translation[0].r;
    assert!(
        (edges - exact).abs() < 0.5 * (plain - exact).abs(),
        "neighbourhood speeds {edges}, own speeds {plain}, exact {exact}"
    );
    assert!((edges - exact).abs() < 0.2 * exact, "{edges} vs {exact}");
}

/// The values' own variances add `π² Σ w_i² Var(L_i)` per channel.
#[test]
fn sample_variances_add_their_noise_to_the_record_variance() {
    let r = rule(KernelKind::SquaredExponential, 0.5, 32);
    let exact: Vec<RadianceSample> = r
        .directions()
        .iter()
        .map(|d| RadianceSample {
            radiance: Rgb::new(1.0 + d.x, 2.0, 0.5 + d.z),
            distance: 1.0,
            variance: Rgb::BLACK,
            direct: Rgb::BLACK,
        })
        .collect();
    let noisy: Vec<RadianceSample> = exact
        .iter()
        .enumerate()
        .map(|(i, s)| RadianceSample {
            variance: Rgb::new(0.01 * i as f64, 0.0, 0.5),
            ..*s
        })
        .collect();
    let (a, b) = (r.estimate(&exact).unwrap(), r.estimate(&noisy).unwrap());
    assert_eq!(a.irradiance, b.irradiance);
    let w = &r.quadrature().weights;
    for c in 0..3 {
        let added: f64 = w
            .iter()
            .zip(&noisy)
            .map(|(w, s)| w * w * s.variance.to_array()[c])
            .sum();
        let got = b.variance.to_array()[c] - a.variance.to_array()[c];
        assert!(
            (got - PI * PI * added).abs() <= 1e-12 * (1.0 + got.abs()),
            "channel {c}"
        );
    }
}

#[test]
fn wrong_sample_count_and_nan_are_typed_errors() {
    let r = rule(KernelKind::SquaredExponential, 0.5, 8);
    assert_eq!(r.estimate(&[]).unwrap_err().field(), Some("samples"));
    let bad = vec![
        RadianceSample {
            radiance: Rgb::splat(f64::NAN),
            distance: 1.0,
            variance: Rgb::BLACK,
            direct: Rgb::BLACK,
        };
        8
    ];
    // Not finite radiance is the scene's doing, not a field of any request.
    let e = r.estimate(&bad).unwrap_err();
    assert_eq!(e.field(), None);
    assert!(
        matches!(e, CacheError::Render(RenderError::NotFinite { .. })),
        "{e}"
    );
}
