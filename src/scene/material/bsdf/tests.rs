//! Every BSDF model through the one interface: sampling agrees with `eval`
//! and `pdf`, energy is conserved (white furnace), two-sided materials see
//! the surface turned around, and the Lambertian split is what the
//! irradiance cache assumes. The models' own files test reciprocity,
//! chi-square sampling and agreement with Mitsuba 3.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::json;

use super::*;
use crate::scene::material::Params;
use crate::scene::material::dielectric::Dielectric;
use crate::scene::material::rough_dielectric::RoughDielectric;

/// The material a document describes (`type` and parameters).
fn material(doc: serde_json::Value) -> Material {
    let mut params = doc.as_object().unwrap().clone();
    let kind = params.remove("type").unwrap();
    let mut params = Params::new("test", params);
    let material = Material::parse(kind.as_str().unwrap(), &mut params, "test").unwrap();
    params.finish().unwrap();
    material
}

/// One material of each model, with unit factors so furnaces can be exact.
fn materials() -> Vec<(&'static str, Material)> {
    let glass = json!({"ext_ior": 1.0, "int_ior": 1.5});
    let with = |kind: &str, base: &serde_json::Value, more: serde_json::Value| {
        let mut doc = base.as_object().unwrap().clone();
        doc.extend(more.as_object().unwrap().clone());
        doc.insert("type".into(), kind.into());
        serde_json::Value::Object(doc)
    };
    let plastic = json!({"type": "plastic", "diffuse_reflectance": [0.2, 0.5, 0.8], "int_ior": 1.49, "ext_ior": 1.0});
    let mirror = json!({"type": "conductor", "eta": 0.0, "k": 1.0});
    let rough_mirror = json!({"type": "roughconductor", "eta": 0.0, "k": 1.0, "distribution": "ggx", "alpha": 0.3});
    let diffuse = json!({"type": "diffuse", "reflectance": 1.0});
    vec![
        ("diffuse", material(diffuse.clone())),
        (
            "glossy",
            material(json!({"type": "glossy", "diffuse": 0.3, "specular": 0.6, "exponent": 30.0})),
        ),
        ("mirror", material(mirror.clone())),
        (
            "rough gold",
            material(
                json!({"type": "roughconductor", "material": "Au", "distribution": "ggx", "alpha": 0.3}),
            ),
        ),
        ("glass", material(with("dielectric", &glass, json!({})))),
        (
            "thin glass",
            material(with("thindielectric", &glass, json!({}))),
        ),
        (
            "rough glass",
            material(with(
                "roughdielectric",
                &glass,
                json!({"distribution": "ggx", "alpha": 0.2}),
            )),
        ),
        ("plastic", material(plastic.clone())),
        (
            "rough plastic",
            material(with("roughplastic", &plastic, json!({"alpha": 0.2}))),
        ),
        (
            "blend",
            material(json!({"type": "blendbsdf", "weight": 0.3, "bsdf": [rough_mirror, plastic]})),
        ),
        (
            "mask",
            material(json!({"type": "mask", "opacity": 0.6, "bsdf": {
                "type": "blendbsdf", "weight": 0.5, "bsdf": [diffuse, mirror]
            }})),
        ),
        (
            "two-sided",
            material(json!({"type": "twosided", "bsdf": [plastic.clone(), diffuse]})),
        ),
        (
            "principled",
            material(
                json!({"type": "principled", "base_color": [0.7, 0.5, 0.3], "metallic": 0.3,
                "sheen": 0.5, "clearcoat": 0.5, "roughness": 0.4}),
            ),
        ),
        (
            "normal-mapped",
            material(json!({"type": "normalmap", "normalmap": [0.65, 0.4, 0.9],
                "bsdf": with("roughplastic", &plastic, json!({"alpha": 0.2}))})),
        ),
    ]
}

fn directions() -> Vec<DVec3> {
    let mut rng = Pcg64::seed_from_u64(3);
    (0..12)
        .map(|_| {
            let z: f64 = rng.random_range(-0.95..0.95);
            let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let r = (1.0 - z * z).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

#[test]
fn samples_agree_with_eval_and_pdf() {
    let mut rng = Pcg64::seed_from_u64(11);
    for (name, material) in materials() {
        let bsdf = Bsdf::from(&material);
        for wo in directions() {
            for _ in 0..200 {
                let Some(s) = bsdf.sample(wo, rng.random(), [rng.random(), rng.random()]) else {
                    // Microfacet warps may land where f = 0; delta and
                    // diffuse lobes always give a direction.
                    let flags = bsdf.flags();
                    assert!(
                        !bsdf.scatters_towards(wo) || !flags.delta || flags.glossy,
                        "{name}: nothing sampled from {wo}"
                    );
                    continue;
                };
                assert!((s.wi.length() - 1.0).abs() < 1e-9, "{name}");
                assert!(s.pdf > 0.0 && s.value.is_finite(), "{name}: {s:?}");
                if s.delta {
                    assert!(bsdf.flags().delta, "{name}");
                    continue;
                }
                let (f, pdf) = (bsdf.eval(wo, s.wi), bsdf.pdf(wo, s.wi));
                assert!(
                    (pdf - s.pdf).abs() <= 1e-6 * pdf,
                    "{name}: {pdf} vs {}",
                    s.pdf
                );
                for (a, b) in f.to_array().iter().zip(s.value.to_array()) {
                    assert!(
                        (a - b).abs() <= 1e-6 * a.abs().max(1e-9),
                        "{name}: {f:?} vs {s:?}"
                    );
                }
            }
        }
    }
}

/// `∫ f |cos θ_i| dω_i` for `wo` by sampling, with its standard error.
fn albedo(bsdf: &Bsdf, wo: DVec3, n: usize, rng: &mut Pcg64) -> (Rgb, f64) {
    let (mut sum, mut sum2) = (Rgb::BLACK, 0.0);
    for _ in 0..n {
        if let Some(s) = bsdf.sample(wo, rng.random(), [rng.random(), rng.random()]) {
            let w = s.value * (s.wi.z.abs() / s.pdf);
            sum += w;
            sum2 += w.max_component().powi(2);
        }
    }
    let n = n as f64;
    let mean = sum * (1.0 / n);
    let var = (sum2 / n - mean.max_component().powi(2)).max(0.0);
    (mean, (var / n).sqrt())
}

#[test]
fn white_furnace_conserves_energy() {
    let mut rng = Pcg64::seed_from_u64(5);
    for (name, material) in materials() {
        let bsdf = Bsdf::from(&material);
        for wo in directions() {
            let (a, se) = albedo(&bsdf, wo, 20_000, &mut rng);
            if !bsdf.scatters_towards(wo) {
                assert!(a.is_black(), "{name} from below: {a:?}");
                continue;
            }
            // In the radiance convention, light refracted into the denser
            // side is concentrated by 1/η², so only the throughput from the
            // denser side may exceed 1 (by up to η²).
            let limit = match (&bsdf, wo.z < 0.0) {
                (Bsdf::Dielectric(Dielectric { eta, .. }), true) => eta * eta,
                (Bsdf::RoughDielectric(RoughDielectric { eta, .. }), true) => eta * eta,
                _ => 1.0,
            };
            assert!(
                a.max_component() <= limit + 4.0 * se + 1e-9,
                "{name} at {wo}: albedo {a:?} ± {se}"
            );
            // Lossless models reflect (or pass) everything.
            let lossless = matches!(name, "diffuse" | "mirror" | "thin glass")
                || (name == "two-sided" && wo.z < 0.0);
            if lossless {
                assert!(
                    (a.min_component() - 1.0).abs() <= 4.0 * se + 1e-9,
                    "{name} at {wo}: albedo {a:?} ± {se}"
                );
            }
        }
    }
}

#[test]
fn two_sided_materials_see_the_surface_turned_around() {
    let front = json!({"type": "plastic", "diffuse_reflectance": [0.2, 0.5, 0.8], "int_ior": 1.49, "ext_ior": 1.0});
    let back = json!({"type": "diffuse", "reflectance": [0.7, 0.1, 0.1]});
    let both = Bsdf::from(&material(
        json!({"type": "twosided", "bsdf": [front, back]}),
    ));
    let (front, back) = (material(front), material(back));
    let (front, back) = (Bsdf::from(&front), Bsdf::from(&back));
    let (wo, wi) = (
        DVec3::new(0.3, 0.1, 0.9).normalize(),
        DVec3::new(-0.5, 0.2, 0.7).normalize(),
    );
    assert_eq!(both.eval(wo, wi), front.eval(wo, wi));
    assert_eq!(both.eval(flip(wo), flip(wi)), back.eval(wo, wi));
    assert_eq!(both.pdf(flip(wo), flip(wi)), back.pdf(wo, wi));
    assert!(
        both.eval(wo, flip(wi)).is_black(),
        "no light passes through"
    );
    let s = both.sample(flip(wo), 0.9, [0.3, 0.6]).unwrap();
    assert!(s.wi.z < 0.0, "the back reflects to its own side");
    assert_eq!(both.lambertian(flip(wo)), back.lambertian(wo));
    // A plain BSDF is black from below.
    assert!(back.eval(flip(wo), flip(wi)).is_black() && !back.scatters_towards(flip(wo)));
}

#[test]
fn the_lambertian_part_is_what_the_cache_may_take_out() {
    let mut rng = Pcg64::seed_from_u64(9);
    for (name, material) in materials() {
        let bsdf = Bsdf::from(&material);
        for wo in directions().into_iter().filter(|w| w.z > 0.0) {
            let rho = bsdf.lambertian(wo);
            assert_eq!(rho.is_black(), !bsdf.flags().diffuse, "{name}");
            for _ in 0..100 {
                let wi = crate::optics::warp::cosine_hemisphere([rng.random(), rng.random()]);
                let rest = bsdf.eval(wo, wi) - rho * std::f64::consts::FRAC_1_PI;
                // Phong's rest is its lobe (≥ 0); plastic's is the coating's
                // loss towards grazing (≤ 0, and at most F(θ_i) − F(0) of it).
                match name {
                    "glossy" => assert!(rest.min_component() >= -1e-12, "{name}: {rest:?}"),
                    // Rough plastic's rest mixes its lobe and the base's
                    // loss, the principled one its lobes and the diffuse
                    // term's departure from its mean; f = ρ/π + rest ≥ 0.
                    "rough plastic" | "principled" => {
                        let f = rest + rho * std::f64::consts::FRAC_1_PI;
                        assert!(f.min_component() >= -1e-12, "{name}: {rest:?}")
                    }
                    "plastic" | "two-sided" => {
                        assert!(rest.max_component() <= 1e-12, "{name}: {rest:?}")
                    }
                    _ => assert!(rest.min_component() >= -1e-12, "{name}: {rest:?}"),
                }
            }
        }
    }
}
