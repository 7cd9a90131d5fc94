//! Irradiance at points of a textured, glass-and-metal Mitsuba 3 scene
//! through the real `bmc-irradiance irradiance` binary, against Mitsuba
//! 3.9.1's `irradiancemeter` at 262,144 samples a point (its directional
//! light's direct part added from Mitsuba's own `sample_direction` and
//! `ray_test`, which a meter cannot receive): `tests/data/mitsuba/
//! materials_irradiance.csv`, made by `docs/validation/
//! mitsuba_irradiance_meter.py`.

use std::path::Path;
use std::process::Command;

/// Relative RMSE within 2 % and bias within 1 % of the mean, over every
/// point and channel, at 4,096 Monte Carlo directions a point (measured:
/// 1.51 % and +0.00 % with this seed, 1.45 % and +0.33 % with seed 1;
/// Mitsuba's own meter at 4,096 samples is 0.49 % from
/// its converged values).
#[test]
fn irradiance_agrees_with_mitsubas_meter() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba");
    let reference = std::fs::read_to_string(dir.join("materials_irradiance.csv")).unwrap();
    let rows: Vec<Vec<f64>> = reference
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    let points: String = std::iter::once("x,y,z,nx,ny,nz".to_string())
        .chain(rows.iter().map(|r| {
            r[..6]
                .iter()
                .map(f64::to_string)
                .collect::<Vec<_>>()
                .join(",")
        }))
        .collect::<Vec<_>>()
        .join("\n");
    let path = std::env::temp_dir().join(format!("bmc-meter-points-{}.csv", std::process::id()));
    std::fs::write(&path, points).unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
        .args(["irradiance", "--scene"])
        .arg(dir.join("materials.xml"))
        .arg("--points")
        .arg(&path)
        .args([
            "--samples",
            "4096",
            "--max-depth",
            "8",
            "--estimator",
            "mc",
            "--seed",
            "5",
        ])
        .output()
        .unwrap();
    std::fs::remove_file(&path).unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let ours: Vec<Vec<f64>> = String::from_utf8(output.stdout)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(ours.len(), rows.len());
    let (mut squared, mut difference, mut total, mut n) = (0.0, 0.0, 0.0, 0.0);
    for (o, m) in ours.iter().zip(&rows) {
        assert_eq!(o[..3], m[..3], "rows keep the input order");
        for c in 0..3 {
            let d = o[3 + c] - m[6 + c];
            squared += d * d;
            difference += d;
            total += m[6 + c];
            n += 1.0;
        }
    }
    let mean = total / n;
    let nrmse = (squared / n).sqrt() / mean;
    let bias = difference / n / mean;
    assert!(
        nrmse < 0.02 && bias.abs() < 0.01,
        "nrmse {nrmse}, bias {bias}"
    );
}

/// The irradiance meters of a Mitsuba scene (`tests/data/mitsuba/meters.xml`:
/// two small disks and a wide one, whose value is the mean over its area)
/// answered by `bmc-irradiance irradiance` without points, against Mitsuba
/// 3.9.1's `irradiancemeter` at 4 M samples each (`meters_mitsuba.csv`, by
/// `docs/validation/mitsuba_meters.py`). The scene's `max_depth` counts
/// from the meter as Mitsuba counts it: read as a camera's depth, one
/// segment fewer, red was 1.7 % low on average. Measured over seeds 1–6
/// at 1,024 samples: rms z 0.63, every |z| < 2, standard errors 0.55 % of
/// the values on average.
#[test]
fn the_scenes_meters_agree_with_mitsubas() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba");
    let parse = |text: &str| -> Vec<(String, Vec<f64>)> {
        text.lines()
            .skip(1)
            .map(|l| {
                let (name, values) = l.split_once(',').unwrap();
                let values = values.split(',').map(|f| f.parse().unwrap()).collect();
                (name.trim_matches('"').to_string(), values)
            })
            .collect()
    };
    let reference = parse(&std::fs::read_to_string(dir.join("meters_mitsuba.csv")).unwrap());
    let output = Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
        .args(["irradiance", "--scene"])
        .arg(dir.join("meters.xml"))
        .args(["--samples", "1024", "--seed", "5"])
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(
        stdout.starts_with("meter,r,g,b,se_r,se_g,se_b\n"),
        "{stdout}"
    );
    let ours = parse(&stdout);
    let names: Vec<_> = ours.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["floor_meter", "wall_meter", "floor_wide"]);
    let mut bias = [0.0; 3];
    for ((name, o), (_, m)) in ours.iter().zip(&reference) {
        for c in 0..3 {
            let z = (o[c] - m[c]) / o[3 + c].hypot(m[3 + c]);
            assert!(z.abs() < 3.5, "{name} channel {c}: {o:?} against {m:?}");
            assert!(
                o[3 + c] < 0.02 * o[c],
                "{name}: an error bar that says something"
            );
            bias[c] += (o[c] / m[c] - 1.0) / 3.0;
        }
    }
    assert!(bias.iter().all(|b| b.abs() < 0.01), "{bias:?}");
}
