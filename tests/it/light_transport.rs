//! Analytic checks of light transport and irradiance through the public API:
//! Lambert's polygon formula, furnace tests, a closed emitting box with a
//! closed-form answer at every depth, environment-map importance sampling
//! and thread-count independence.

use std::f64::consts::{PI, TAU};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use bmc_irradiance::render::Cancel;
use bmc_irradiance::render::MeanEstimate;
use bmc_irradiance::render::polygon::projected_solid_angle;
use bmc_irradiance::render::seed::point_rng;
use bmc_irradiance::render::{
    IrradianceEstimate, IrradianceMethod, IrradianceOptions, PathDepth, PathLengths, PathLimits,
    QueryPoint, Rgb, TraceStats, Transport,
};
use bmc_irradiance::scene::{Environment, Scene};
use bmc_irradiance::sphere::Frame;
use bmc_irradiance::testing::agrees;
use glam::DVec3;

const CAMERA: &str = r#"{"fov": 40, "width": 8, "height": 8, "origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}"#;

/// A rectangle shape centred at `c` with front normal `n`, half sizes `sx`
/// along `t` and `sy` along `n × t`, as scene JSON. The `to_world` matrix has
/// the right-handed columns `(t·sx, (n×t)·sy, n)`, so the rectangle's local
/// +z (its front) maps to `n`. `emitter` is its radiance, if it is a light.
fn rectangle(
    c: DVec3,
    n: DVec3,
    t: DVec3,
    (sx, sy): (f64, f64),
    material: &str,
    emitter: Option<[f64; 3]>,
) -> String {
    let (a, b) = (t * sx, n.cross(t) * sy);
    let emitter = emitter.map_or(String::new(), |[r, g, b]| {
        format!(r#", "emitter": {{"type": "area", "radiance": [{r}, {g}, {b}]}}"#)
    });
    format!(
        r#"{{"type": "rectangle", "material": "{material}", "to_world": [{{"matrix": [[{}, {}, {}, {}], [{}, {}, {}, {}], [{}, {}, {}, {}], [0, 0, 0, 1]]}}]{emitter}}}"#,
        a.x, b.x, n.x, c.x, a.y, b.y, n.y, c.y, a.z, b.z, n.z, c.z
    )
}

/// Walls of the cube [-1, 1]³ facing inwards; `material(i)` and
/// `emitter(i)` choose per face. Face 5 is the top (z = 1); `faces` < 6
/// leaves the box open at the top.
fn box_walls(
    faces: usize,
    material: impl Fn(usize) -> &'static str,
    emitter: impl Fn(usize) -> Option<[f64; 3]>,
) -> Vec<String> {
    inward_faces()[..faces]
        .iter()
        .enumerate()
        .map(|(i, &(c, n, t))| rectangle(c, n, t, (1.0, 1.0), material(i), emitter(i)))
        .collect()
}

/// The faces of the cube [-1, 1]³ with normals pointing inwards, as
/// `(centre, inward normal, tangent)`; the top face (z = 1) comes last.
fn inward_faces() -> Vec<(DVec3, DVec3, DVec3)> {
    vec![
        (-DVec3::Z, DVec3::Z, DVec3::X),
        (-DVec3::X, DVec3::X, DVec3::Y),
        (DVec3::X, -DVec3::X, DVec3::Y),
        (-DVec3::Y, DVec3::Y, DVec3::Z),
        (DVec3::Y, -DVec3::Y, DVec3::Z),
        (DVec3::Z, -DVec3::Z, DVec3::X),
    ]
}

fn scene_json(materials: &str, shapes: &[String], environment: Option<&str>) -> String {
    let env = environment.map_or(String::new(), |e| format!(", \"environment\": {e}"));
    format!(
        "{{\"materials\": {materials}, \"shapes\": [{}]{env}, \"camera\": {CAMERA}}}",
        shapes.join(", ")
    )
}

fn load(json: &str, dir: &Path) -> Transport {
    let scene = Scene::from_json_str(json, dir, dir).expect("test scene is valid");
    Transport::new(Arc::new(scene))
}

fn estimate(
    t: &Transport,
    points: &[QueryPoint],
    options: IrradianceOptions,
) -> Vec<IrradianceEstimate> {
    t.irradiance_at_points(points, &options, &|| {}, &Cancel::never())
        .expect("valid options")
}

/// `|got − expected| ≤ 4 standard errors + rel · |expected|` per channel.
fn assert_close(got: &IrradianceEstimate, expected: Rgb, rel: f64, what: &str) {
    for c in 0..3 {
        let (g, e, s) = (
            got.irradiance.to_array()[c],
            expected.to_array()[c],
            got.std_error.to_array()[c],
        );
        assert!(
            agrees(g, e, s, 4.0, rel) || (g - e).abs() <= 1e-12,
            "{what}: channel {c}: got {g} ± {s}, expected {e}"
        );
    }
}

fn options(samples: u32, max_depth: u32, method: IrradianceMethod) -> IrradianceOptions {
    IrradianceOptions {
        samples,
        light_samples: None,
        max_depth: PathDepth::new(max_depth).unwrap(),
        direct_only: false,
        method,
        seed: 7,
    }
}

fn point(p: DVec3, n: DVec3) -> QueryPoint {
    QueryPoint::new(p, n).expect("valid point")
}

const METHODS: [IrradianceMethod; 2] = [IrradianceMethod::Split, IrradianceMethod::Hemisphere];

#[test]
fn rectangle_light_matches_lamberts_formula() {
    // A 1 × 1.6 light facing down at z = 1, centred at (0.3, -0.2).
    let (c, half) = (DVec3::new(0.3, -0.2, 1.0), DVec3::new(0.5, 0.8, 0.0));
    let light = rectangle(
        c,
        -DVec3::Z,
        DVec3::X,
        (half.x, half.y),
        "black",
        Some([1.0, 2.0, 3.0]),
    );
    let materials = r#"[{"id": "black", "type": "diffuse", "reflectance": [0, 0, 0]}]"#;
    let t = load(&scene_json(materials, &[light], None), Path::new("."));
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(sx, sy)| c + DVec3::new(sx * half.x, sy * half.y, 0.0));
    let points = [
        point(DVec3::ZERO, DVec3::Z),
        // Tilted so that part of the light is below the tangent plane.
        point(DVec3::new(0.0, 0.0, 0.2), DVec3::new(1.0, 0.2, 0.1)),
        // Above the light: it sees the light's back, which does not emit.
        point(DVec3::new(0.3, -0.2, 1.5), -DVec3::Z),
    ];
    for method in METHODS {
        let o = IrradianceOptions {
            direct_only: true,
            ..options(8192, 16, method)
        };
        let got = estimate(&t, &points, o);
        for (p, e) in points.iter().zip(&got) {
            assert!(
                e.rays <= 8192,
                "direct light traces at most one ray per sample"
            );
            let psa = projected_solid_angle(p.position(), p.normal(), &corners);
            assert!(
                psa > 0.05,
                "every point has the light in its hemisphere: {psa}"
            );
            if p.normal().z > 0.0 {
                assert_close(
                    e,
                    Rgb::new(1.0, 2.0, 3.0) * psa,
                    0.0,
                    &format!("{method:?} {p:?}"),
                );
            } else {
                assert_eq!(
                    e.irradiance,
                    Rgb::BLACK,
                    "{method:?}: the back of a light is dark"
                );
            }
        }
    }
}

/// Open-topped box of albedo 1 under a constant sky: in equilibrium every
/// surface reflects exactly what it receives, so `E = πL` everywhere inside.
#[test]
fn furnace_open_white_box_under_constant_sky() {
    let sky = Rgb::new(0.5, 1.0, 2.0);
    let shapes = box_walls(5, |_| "white", |_| None);
    let materials = r#"[{"id": "white", "type": "diffuse", "reflectance": [1, 1, 1]}]"#;
    let env = r#"{"type": "constant", "radiance": [0.5, 1, 2]}"#;
    let t = load(&scene_json(materials, &shapes, Some(env)), Path::new("."));
    let points = [
        point(DVec3::new(0.0, 0.0, -1.0), DVec3::Z),
        point(DVec3::new(-1.0, 0.3, -0.5), DVec3::X),
        point(DVec3::new(0.2, -0.1, 0.0), DVec3::new(0.3, -0.5, 1.0)),
    ];
    let opening =
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(x, y)| DVec3::new(x, y, 1.0));
    for method in METHODS {
        let full = estimate(&t, &points, options(1024, 100, method));
        let direct = estimate(&t, &points, options(4096, 1, method));
        for (i, p) in points.iter().enumerate() {
            assert_close(&full[i], sky * PI, 1e-4, &format!("{method:?} full {p:?}"));
            let psa = projected_solid_angle(p.position(), p.normal(), &opening);
            assert_close(
                &direct[i],
                sky * psa,
                0.0,
                &format!("{method:?} direct {p:?}"),
            );
        }
    }
}

/// Closed box whose walls (albedo ρ) all emit `L_e` inwards: radiance is
/// uniform and paths of length ≤ D carry `L_e Σ_{k<D} ρ^k`, so
/// `E_D = π L_e (1 − ρ^D)/(1 − ρ)` exactly, for every depth D.
#[test]
fn closed_emitting_box_conserves_energy_at_every_depth() {
    let le = Rgb::new(1.0, 0.5, 0.25);
    let rho = Rgb::new(0.5, 0.25, 0.75);
    let shapes = box_walls(6, |_| "wall", |_| Some(le.to_array()));
    let materials = r#"[{"id": "wall", "type": "diffuse", "reflectance": [0.5, 0.25, 0.75]}]"#;
    let t = load(&scene_json(materials, &shapes, None), Path::new("."));
    let points = [
        point(DVec3::new(0.1, 0.2, -1.0), DVec3::Z),
        point(DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 1.0, 1.0)),
    ];
    for method in METHODS {
        for depth in [1, 2, 3, 64] {
            let truncated = Rgb::WHITE - rho.map(|r| r.powi(depth as i32));
            let expected = le * PI * truncated * rho.map(|r| 1.0 / (1.0 - r));
            let got = estimate(&t, &points, options(2048, depth, method));
            for e in &got {
                assert_close(e, expected, 2e-6, &format!("{method:?} depth {depth}"));
            }
        }
    }
}

/// The hook for external hemisphere estimators (BMC, QMC): caller-chosen
/// local directions in a rotated frame come back as radiance samples whose
/// equal-weight average times π is the irradiance for cosine-distributed sets.
#[test]
fn external_direction_sets_plug_into_the_hemisphere_estimate() {
    let le = Rgb::new(1.0, 0.5, 0.25);
    let shapes = box_walls(6, |_| "wall", |_| Some(le.to_array()));
    let materials = r#"[{"id": "wall", "type": "diffuse", "reflectance": [0.5, 0.25, 0.75]}]"#;
    let t = load(&scene_json(materials, &shapes, None), Path::new("."));
    let p = point(DVec3::new(0.1, 0.2, -1.0), DVec3::Z);
    let frame = Frame::from_normal(p.normal()).rotated_about_normal(0.7);
    // Cosine-distributed spherical Fibonacci set (docs/math.md §5) plus a
    // direction below the surface and a NaN one, which must carry nothing.
    let n = 64;
    let golden = (1.0 + 5f64.sqrt()) / 2.0;
    let mut dirs: Vec<DVec3> = (0..n)
        .map(|i| {
            let cos = (1.0 - (i as f64 + 0.5) / n as f64).sqrt();
            let phi = TAU * (i as f64 / golden).fract();
            let sin = (1.0 - cos * cos).sqrt();
            DVec3::new(sin * phi.cos(), sin * phi.sin(), cos)
        })
        .collect();
    dirs.push(-DVec3::Z);
    dirs.push(DVec3::new(0.0, f64::NAN, 1.0));
    let mut rng = point_rng(3, 0);
    let mut stats = TraceStats::default();
    let limits = |max_depth, lengths| PathLimits {
        max_depth: PathDepth::new(max_depth).unwrap(),
        lengths,
    };
    let direct = t.hemisphere_samples(
        &p,
        &frame,
        &dirs,
        limits(1, PathLengths::All),
        &mut rng,
        &mut stats,
    );
    assert_eq!(
        stats.rays, n as u64,
        "one ray per direction above the surface"
    );
    for s in &direct[..n] {
        assert_eq!(s.radiance, le, "every direction sees an emitting wall");
        assert!(s.distance > 0.0 && s.distance < 2.0 * 3f64.sqrt());
    }
    assert!(direct[n..].iter().all(|s| s.radiance == Rgb::BLACK));
    let mean: Rgb = direct[..n].iter().map(|s| s.radiance).sum::<Rgb>() / n as f64;
    assert!(((mean * PI).r - PI * le.r).abs() < 1e-12);
    // Without the directly seen emission and one bounce, nothing is left.
    let none = t.hemisphere_samples(
        &p,
        &frame,
        &dirs,
        limits(1, PathLengths::Indirect),
        &mut rng,
        &mut stats,
    );
    assert!(none.iter().all(|s| s.radiance == Rgb::BLACK));
}

/// The two decompositions estimate the same integral, including glossy
/// reflection with MIS at every bounce.
#[test]
fn split_and_hemisphere_methods_agree_with_glossy_surfaces() {
    let materials = r#"[
        {"id": "white", "type": "diffuse", "reflectance": [0.7, 0.7, 0.7]},
        {"id": "shiny", "type": "glossy", "diffuse": [0.2, 0.3, 0.1], "specular": [0.5, 0.4, 0.6], "exponent": 30}]"#;
    let material = |i| if i % 2 == 0 { "shiny" } else { "white" };
    let mut shapes = box_walls(6, material, |_| None);
    shapes.push(rectangle(
        DVec3::new(0.0, 0.0, 0.99),
        -DVec3::Z,
        DVec3::X,
        (0.25, 0.25),
        "white",
        Some([10.0, 8.0, 6.0]),
    ));
    let t = load(&scene_json(materials, &shapes, None), Path::new("."));
    let points = [
        point(DVec3::new(0.3, -0.4, -1.0), DVec3::Z),
        point(DVec3::new(-1.0, 0.5, 0.2), DVec3::X),
    ];
    let split = estimate(&t, &points, options(4096, 5, IrradianceMethod::Split));
    let hemi = estimate(&t, &points, options(4096, 5, IrradianceMethod::Hemisphere));
    for (a, b) in split.iter().zip(&hemi) {
        for c in 0..3 {
            let (x, y) = (a.irradiance.to_array()[c], b.irradiance.to_array()[c]);
            let s = a.std_error.to_array()[c].hypot(b.std_error.to_array()[c]);
            assert!(
                agrees(x, y, s, 4.0, 0.0),
                "channel {c}: split {x} vs hemisphere {y} ± {s}"
            );
            assert!(x > 0.0);
        }
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("bmc-irradiance-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// A sky with a sharp sun: importance sampling the map (split) and cosine
/// sampling (hemisphere) both match the exact texel sum.
#[test]
fn environment_map_importance_sampling_is_unbiased() {
    let (w, h) = (64usize, 32usize);
    let sun = DVec3::new(0.3, 0.8, -0.52).normalize();
    let texels: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (phi, theta) = (
                TAU * (x as f64 + 0.5) / w as f64,
                PI * (y as f64 + 0.5) / h as f64,
            );
            // Same lat-long convention as the loader: +y is the pole.
            let d = DVec3::new(
                phi.sin() * theta.sin(),
                theta.cos(),
                -phi.cos() * theta.sin(),
            );
            let s = 0.2 + 200.0 * (40.0 * (d.dot(sun) - 1.0)).exp();
            [s as f32, (0.5 * s) as f32, 0.3]
        })
        .collect();
    let dir = temp_dir("envmap");
    bmc_irradiance::scene::write_exr_half(&dir.join("sky.exr"), w, h, &texels).expect("write exr");
    let materials = r#"[{"id": "black", "type": "diffuse", "reflectance": [0, 0, 0]}]"#;
    let far_disk =
        r#"{"type": "disk", "material": "black", "to_world": [{"translate": [0, -100, 0]}]}"#;
    let env = r#"{"type": "envmap", "filename": "sky.exr"}"#;
    let t = load(
        &scene_json(materials, &[far_disk.to_string()], Some(env)),
        &dir,
    );
    let Some(Environment::Map(map)) = &t.scene().environment else {
        panic!("scene has an environment map");
    };
    // Normal +y is the map's pole: `E = ∫ L cos θ sin θ dθ dφ` over the
    // upper half of the map, `θ = π v`, `φ = 2π u`. The radiance is
    // bilinear between texel centres, so on 16 × 16 cells per texel, each
    // with its radiance at its centre and its band's `∫ cos θ dω =
    // (2π/cells) (sin²θ₁ − sin²θ₀)/2` exactly, the sum is exact to about
    // 10⁻⁵, far below the estimates' error bars (the texels' values over
    // their bands, piecewise constant, are 0.4 % low, which stratified light
    // samples with 0.1 % error bars revealed: docs/BENCHMARKS.md, stop 57).
    let (su, sv) = (16 * w, 16 * h);
    let mut exact = Rgb::BLACK;
    for j in 0..sv / 2 {
        let v = (j as f64 + 0.5) / sv as f64;
        let (t0, t1) = (PI * j as f64 / sv as f64, PI * (j + 1) as f64 / sv as f64);
        let weight = TAU / su as f64 * (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0;
        for i in 0..su {
            let u = (i as f64 + 0.5) / su as f64;
            exact += Rgb::from_array(map.radiance_at_uv(u, v)) * weight;
        }
    }
    let points = [point(DVec3::ZERO, DVec3::Y)];
    let [split, hemi] = METHODS.map(|m| estimate(&t, &points, options(8192, 1, m)));
    assert_close(&split[0], exact, 0.0, "importance sampled");
    assert_close(&hemi[0], exact, 0.0, "cosine sampled");
    // The sun dominates, so importance sampling must be much less noisy.
    assert!(
        split[0].std_error.r < 0.5 * hemi[0].std_error.r,
        "{:?} vs {:?}",
        split[0],
        hemi[0]
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let shapes = box_walls(6, |_| "wall", |i| (i == 5).then_some([3.0; 3]));
    let materials = r#"[{"id": "wall", "type": "diffuse", "reflectance": [0.6, 0.5, 0.4]}]"#;
    let t = load(&scene_json(materials, &shapes, None), Path::new("."));
    let points: Vec<QueryPoint> = (0..12)
        .map(|i| point(DVec3::new(-0.9 + 0.15 * i as f64, 0.1, -1.0), DVec3::Z))
        .collect();
    let o = options(64, 8, IrradianceMethod::Split);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| estimate(&t, &points, o))
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one, two);
    assert_ne!(one[0].irradiance, one[1].irradiance);
    let reseeded = estimate(&t, &points, IrradianceOptions { seed: 8, ..o });
    assert_ne!(reseeded, one);
}

/// Paths that share their first segment (`incident_radiance_averaged`, used
/// by irradiance-cache records) estimate the same radiance as independent
/// paths, with fewer rays: in the closed emitting box (every path carries
/// `L_e Σ_{k<D} ρ^k` there in expectation), and under a light over a floor,
/// where the one-bounce term dominates and the stratified light samples at
/// the shared hit lower the spread.
#[test]
fn paths_sharing_a_first_segment_are_unbiased_and_cheaper() {
    // Mean and standard error of channel `c`.
    let channel = |e: &MeanEstimate, c: usize| {
        (
            e.mean.to_array()[c],
            e.variance_of_mean.to_array()[c].sqrt(),
        )
    };
    let le = Rgb::new(1.0, 0.5, 0.25);
    let rho = Rgb::new(0.5, 0.25, 0.75);
    let shapes = box_walls(6, |_| "wall", |_| Some(le.to_array()));
    let materials = r#"[{"id": "wall", "type": "diffuse", "reflectance": [0.5, 0.25, 0.75]}]"#;
    let t = load(&scene_json(materials, &shapes, None), Path::new("."));
    let dir = DVec3::new(0.3, 0.2, 0.9).normalize();
    let from = t
        .scene()
        .spawn_ray(DVec3::new(0.1, 0.2, -1.0), DVec3::Z, dir);
    for depth in [1, 2, 3, 6] {
        let expected =
            le * (Rgb::WHITE - rho.map(|r| r.powi(depth as i32))) * rho.map(|r| 1.0 / (1.0 - r));
        let limits = PathLimits {
            max_depth: PathDepth::new(depth).unwrap(),
            lengths: PathLengths::All,
        };
        let mut rng = point_rng(3, u64::from(depth));
        let (mut shared, mut single) = (TraceStats::default(), TraceStats::default());
        let estimate = MeanEstimate::of((0..2000).map(|_| {
            (0..4).for_each(|_| {
                t.paths()
                    .incident_radiance(from, limits, &mut rng, &mut single);
            });
            t.paths()
                .incident_radiance_averaged(from, limits, 4, &mut rng, &mut shared)
                .radiance
        }));
        for c in 0..3 {
            let (m, e) = channel(&estimate, c);
            let want = expected.to_array()[c];
            assert!(
                agrees(m, want, e, 4.0, 1e-9),
                "depth {depth} channel {c}: {m} ± {e} vs {want}"
            );
        }
        if depth == 1 {
            assert_eq!(shared.rays * 4, single.rays, "only the first segment");
        } else {
            assert!(
                shared.rays < single.rays,
                "depth {depth}: {} rays shared vs {} single",
                shared.rays,
                single.rays
            );
        }
    }

    let light = rectangle(
        DVec3::new(0.0, 0.0, 1.0),
        -DVec3::Z,
        DVec3::X,
        (0.3, 0.3),
        "grey",
        Some([5.0, 5.0, 5.0]),
    );
    let floor = rectangle(DVec3::ZERO, DVec3::Z, DVec3::X, (2.0, 2.0), "grey", None);
    let materials = r#"[{"id": "grey", "type": "diffuse", "reflectance": [0.6, 0.6, 0.6]}]"#;
    let t = load(
        &scene_json(materials, &[light, floor], None),
        Path::new("."),
    );
    let limits = PathLimits {
        max_depth: PathDepth::constant(8),
        lengths: PathLengths::Indirect,
    };
    let dir = DVec3::new(0.2, -0.1, -1.0).normalize();
    let ray = t
        .scene()
        .spawn_ray(DVec3::new(0.2, 0.1, 0.5), DVec3::Z, dir);
    let mut rng = point_rng(5, 0);
    let mut stats = TraceStats::default();
    let shared = MeanEstimate::of((0..4000).map(|_| {
        t.paths()
            .incident_radiance_averaged(ray, limits, 8, &mut rng, &mut stats)
            .radiance
    }));
    let single = MeanEstimate::of((0..4000).map(|_| {
        (0..8).fold(Rgb::BLACK, |sum, _| {
            sum + t
                .paths()
                .incident_radiance(ray, limits, &mut rng, &mut stats)
                .radiance
        }) * (1.0 / 8.0)
    }));
    let ((ms, es), (mi, ei)) = (channel(&shared, 1), channel(&single, 1));
    assert!(ms > 0.0 && mi > 0.0);
    assert!(
        agrees(ms, mi, es.hypot(ei), 4.0, 0.0),
        "shared {ms} ± {es} vs single {mi} ± {ei}"
    );
    assert!(
        es < ei,
        "stratified light samples at the shared hit: {es} should be below {ei}"
    );
}
