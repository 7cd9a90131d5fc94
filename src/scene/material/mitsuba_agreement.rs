//! The rough lobes against Mitsuba 3's own `roughconductor` and
//! `roughdielectric` at fixed direction pairs (`tests/data/mitsuba_bsdf_lobes.json`,
//! made by `docs/validation/mitsuba_bsdf_lobes.py`): the same BSDF values,
//! and for GGX, which both sample by visible normals, the same densities.

use glam::DVec3;
use serde::Deserialize;

use super::rough_conductor::RoughConductor;
use super::rough_dielectric::RoughDielectric;
use crate::color::Rgb;
use crate::optics::microfacet::{Microfacet, MicrofacetKind};

#[derive(Deserialize)]
struct Reference {
    conductor: Conductor,
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Conductor {
    eta: [f64; 3],
    k: [f64; 3],
}

#[derive(Deserialize)]
struct Case {
    kind: String,
    distribution: String,
    alpha: [f64; 2],
    eta: f64,
    wo: [f64; 3],
    wi: [f64; 3],
    value: [f64; 3],
    pdf: f64,
}

/// Whether two values agree to `relative`, above an absolute floor.
fn close(ours: f64, theirs: f64, relative: f64) -> bool {
    (ours - theirs).abs() <= relative * theirs.abs().max(ours.abs()) + 1e-6
}

#[test]
fn rough_lobes_agree_with_mitsuba() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/mitsuba_bsdf_lobes.json"
    );
    let reference: Reference =
        serde_json::from_str(&std::fs::read_to_string(path).expect("reference file")).unwrap();
    let mut failures = Vec::new();
    for case in &reference.cases {
        let kind = match case.distribution.as_str() {
            "ggx" => MicrofacetKind::Ggx,
            _ => MicrofacetKind::Beckmann,
        };
        let distribution = Microfacet::new(kind, case.alpha[0], case.alpha[1]).unwrap();
        let (wo, wi) = (DVec3::from(case.wo), DVec3::from(case.wi));
        let (value, pdf) = if case.kind == "roughconductor" {
            let lobe = RoughConductor {
                distribution,
                eta: Rgb::from_array(reference.conductor.eta),
                k: Rgb::from_array(reference.conductor.k),
                specular_reflectance: Rgb::WHITE,
            };
            (lobe.eval(wo, wi), lobe.pdf(wo, wi))
        } else {
            let lobe = RoughDielectric {
                distribution,
                eta: case.eta,
                specular_reflectance: Rgb::WHITE,
                specular_transmittance: Rgb::WHITE,
            };
            (lobe.eval(wo, wi), lobe.pdf(wo, wi))
        };
        // Mitsuba computes in single precision (2e-4), and its Beckmann
        // masking is Walter et al.'s rational fit of G1 (eq. 27), which
        // differs from the exact Λ used here by up to 0.4 %; both sample
        // visible normals, whose density holds G1 too.
        let relative = match kind {
            MicrofacetKind::Ggx => 2e-4,
            MicrofacetKind::Beckmann => 4e-3,
        };
        let value_ok = (0..3).all(|c| close(value.to_array()[c], case.value[c], relative));
        let pdf_ok = close(pdf, case.pdf, relative);
        if !(value_ok && pdf_ok) {
            failures.push(format!(
                "{} {} α {:?} wo {:?} wi {:?}: value {:?} vs {:?}, pdf {pdf} vs {}",
                case.kind,
                case.distribution,
                case.alpha,
                case.wo,
                case.wi,
                value.to_array(),
                case.value,
                case.pdf
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases differ:\n{}",
        failures.len(),
        reference.cases.len(),
        failures.join("\n")
    );
}
