//! Error bars are calibrated (docs/math.md §10.3, §10.5) on a reduced real-scene
//! study: 40 camera-visible points × 8 seeds on two bundled scenes, checked
//! against converged references on points the calibration never saw.

use std::path::Path;
use std::sync::Arc;

use bmc_irradiance::integrator::Preset;
use bmc_irradiance::render::{IrradianceMethod, PathDepth, Transport};
use bmc_irradiance::scene::Scene;
use bmc_irradiance::study::scenes::{self, SceneStudyOptions};

fn transport(name: &str) -> Transport {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    Transport::new(Arc::new(Scene::load(&dir.join(name), &dir).unwrap()))
}

#[test]
fn mc_qmc_and_bmc_error_bars_are_calibrated_on_two_scenes() {
    // The overcast scene under `auto` (hemisphere, environment prior for
    // BMC) and the Cornell box under `auto` (split), with short paths to keep
    // the references cheap.
    // On the Cornell box also with the records prior (§10.7), on records a
    // preview render of the camera image leaves.
    for (scene, max_depth, records_from) in [
        ("overcast.json", 2, None),
        ("cornell-box.json", 3, Some(Preset::Preview)),
    ] {
        let options = SceneStudyOptions {
            points: 40,
            seeds: 8,
            sample_counts: vec![64],
            decomposition: IrradianceMethod::Auto,
            max_depth: PathDepth::constant(max_depth),
            reference_samples: 8192,
            seed: 2026,
            bmc_kernel: None,
            records_from,
        };
        let rows = scenes::run(&transport(scene), scene, &options).unwrap();
        assert!(rows.iter().any(|r| r.estimator == "bmc"));
        let nrmse = |name: &str| rows.iter().find(|r| r.estimator == name).map(|r| r.nrmse);
        if records_from.is_some() {
            // The records carry what 64 samples cannot: measured 0.39× at
            // N = 64 on 200 points (docs/BENCHMARKS.md, records prior).
            let (with, plain) = (nrmse("bmc+records").unwrap(), nrmse("qmc").unwrap());
            assert!(with < 0.7 * plain, "bmc+records {with} vs qmc {plain}");
        }
        for row in rows {
            // The default error bars: MC's own sample variance, calibrated
            // ones for QMC and BMC (docs/math.md §10.5), with the records
            // prior too (§10.7).
            let (coverage, rms_z) = if row.estimator == "mc" {
                (row.model_coverage, row.model_rms_z)
            } else {
                (row.coverage, row.rms_z)
            };
            assert!(
                (0.90..=0.98).contains(&coverage) && (0.75..=1.3).contains(&rms_z),
                "{scene} {} N={}: coverage {coverage:.3}, rms z {rms_z:.2}",
                row.estimator,
                row.samples,
            );
        }
    }
}
