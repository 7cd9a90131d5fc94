use crate::scene::bitmap::Bitmaps;
use crate::scene::budget::{Budget, LoadLimits};
use crate::scene::texture::Texture;
use serde_json::json;

use super::Interface;
use super::conductor::ConductorMaterial;
use super::dielectric::DielectricMaterial;
use super::rough_conductor::RoughConductorMaterial;
use super::rough_plastic::RoughPlasticMaterial;
use super::thin_dielectric::ThinDielectricMaterial;
use super::twosided::TwoSidedMaterial;
use super::*;

fn parse(doc: serde_json::Value) -> Result<Material, SceneError> {
    let doc: MaterialDoc = serde_json::from_value(doc).unwrap();
    let dir = std::env::temp_dir();
    let files = crate::scene::files::Files::new(&dir, &dir).unwrap();
    let budget = Budget::new(&LoadLimits::default());
    let declared = crate::scene::material::Declared::new();
    Material::from_doc(
        &doc,
        "materials[3]",
        &Bitmaps::new(&files, &budget),
        &declared,
    )
}

fn field_of(doc: serde_json::Value) -> String {
    match parse(doc) {
        Err(SceneError::Invalid { field, .. }) => field,
        other => panic!("expected an invalid field, got {other:?}"),
    }
}

#[test]
fn every_plugin_parses_with_mitsubas_defaults() {
    let gold = parse(
        json!({"id": "g", "type": "roughconductor", "material": "Au", "distribution": "ggx"}),
    );
    let Ok(Material::RoughConductor(RoughConductorMaterial {
        eta,
        roughness: r,
        specular_reflectance,
        ..
    })) = gold
    else {
        panic!("{gold:?}")
    };
    assert_eq!(eta, metals::named_metal("Au").unwrap().0);
    assert_eq!(
        (r.distribution, r.alpha_u, r.alpha_v),
        (Distribution::Ggx, 0.1, 0.1)
    );
    assert_eq!(specular_reflectance, Texture::from([1.0; 3]));
    assert_eq!(
        parse(json!({"id": "m", "type": "conductor"})).unwrap(),
        Material::Conductor(ConductorMaterial {
            eta: [0.0; 3],
            k: [1.0; 3],
            specular_reflectance: Texture::from([1.0; 3]),
        }),
        "Mitsuba's default conductor is the perfect mirror `none`"
    );
    let Ok(Material::ThinDielectric(ThinDielectricMaterial(Interface { eta, .. }))) =
        parse(json!({"id": "w", "type": "thindielectric", "int_ior": "water", "ext_ior": 1.0}))
    else {
        panic!()
    };
    assert!((eta - 1.333).abs() < 1e-12);
    let Ok(Material::Dielectric(DielectricMaterial(Interface { eta, .. }))) =
        parse(json!({"id": "d", "type": "dielectric"}))
    else {
        panic!()
    };
    assert!((eta - 1.5046 / ior::AIR).abs() < 1e-12, "BK7 in air");
    let Ok(Material::RoughPlastic(RoughPlasticMaterial {
        diffuse_reflectance,
        roughness: r,
        ..
    })) =
        parse(json!({"id": "p", "type": "roughplastic", "diffuse_reflectance": 0.3, "alpha": 0.2}))
    else {
        panic!()
    };
    assert_eq!(diffuse_reflectance, Texture::from([0.3; 3]));
    assert_eq!((r.distribution, r.alpha_u), (Distribution::Beckmann, 0.2));
    let two = parse(json!({"id": "t", "type": "twosided", "bsdf": [
        {"type": "diffuse", "reflectance": [0.1, 0.2, 0.3]},
        {"type": "plastic"}
    ]}))
    .unwrap();
    let Material::TwoSided(TwoSidedMaterial { front, back }) = two else {
        panic!()
    };
    assert!(matches!(*front, Material::Diffuse(_)) && matches!(*back, Material::Plastic(_)));
}

#[test]
fn bad_parameters_are_named_by_their_field() {
    let cases = [
        (json!({"id": "x", "type": "velvet"}), "materials[3].type"),
        (json!({"id": "x", "type": "diffuse"}), "materials[3]"),
        (
            json!({"id": "x", "type": "diffuse", "reflectance": 1, "alpha": 2}),
            "materials[3].alpha",
        ),
        (
            json!({"id": "x", "type": "diffuse", "reflectance": [0.5, 1.5, 0.5]}),
            "materials[3].reflectance[1]",
        ),
        (
            json!({"id": "x", "type": "dielectric", "int_ior": "glassy"}),
            "materials[3].int_ior",
        ),
        (
            json!({"id": "x", "type": "dielectric", "int_ior": 1.0, "ext_ior": 1.0}),
            "materials[3].int_ior",
        ),
        (
            json!({"id": "x", "type": "conductor", "eta": 0.2}),
            "materials[3].eta",
        ),
        (
            json!({"id": "x", "type": "conductor", "material": "Mithril"}),
            "materials[3].material",
        ),
        (
            json!({"id": "x", "type": "roughconductor", "alpha": 0}),
            "materials[3].alpha",
        ),
        (
            json!({"id": "x", "type": "roughconductor", "alpha_u": 0.1}),
            "materials[3].alpha",
        ),
        (
            json!({"id": "x", "type": "roughconductor", "distribution": "phong"}),
            "materials[3].distribution",
        ),
        (
            json!({"id": "x", "type": "roughplastic", "alpha_u": 0.1, "alpha_v": 0.3}),
            "materials[3].alpha_u",
        ),
        (
            json!({"id": "x", "type": "plastic", "nonlinear": "yes"}),
            "materials[3].nonlinear",
        ),
        (
            json!({"id": "x", "type": "glossy", "diffuse": 0.6, "specular": 0.6, "exponent": 5}),
            "materials[3].specular[0]",
        ),
        (
            json!({"id": "x", "type": "twosided", "bsdf": []}),
            "materials[3].bsdf",
        ),
        (
            json!({"id": "x", "type": "twosided", "bsdf": {"type": "dielectric"}}),
            "materials[3].bsdf[0].type",
        ),
        (
            json!({"id": "x", "type": "twosided", "bsdf": {"type": "diffuse", "reflectance": 2}}),
            "materials[3].bsdf[0].reflectance[0]",
        ),
        (
            json!({"id": "x", "type": "twosided", "bsdf": {"type": "diffuse", "reflectance": 0.5, "k": 1}}),
            "materials[3].bsdf[0].k",
        ),
    ];
    for (doc, field) in cases {
        assert_eq!(field_of(doc.clone()), field, "{doc}");
    }
}

#[test]
fn roughness_maps_are_textures_on_conductors_and_dielectrics_only() {
    let checker = json!({"type": "checkerboard", "color0": 0.05, "color1": 0.4});
    let Ok(Material::RoughConductor(RoughConductorMaterial { roughness: r, .. })) =
        parse(json!({"id": "c", "type": "roughconductor", "alpha_u": checker, "alpha_v": 0.2}))
    else {
        panic!()
    };
    // The mean stands where no point is at hand; lookups follow the map
    // (the checkerboard's scalar lookup swaps its colours, as Mitsuba's).
    assert!(
        (r.alpha_u - 0.225).abs() < 1e-12 && r.alpha_v == 0.2,
        "{r:?}"
    );
    let (u, v) = r.at(glam::DVec2::new(0.25, 0.25));
    assert!(
        (u - 0.4).abs() < 1e-12 && (v - 0.2).abs() < 1e-12,
        "{u} {v}"
    );
    assert!(
        Material::RoughConductor(RoughConductorMaterial {
            eta: [0.2; 3],
            k: [3.0; 3],
            specular_reflectance: Texture::from([1.0; 3]),
            roughness: r,
        })
        .is_textured()
    );
    let too_rough = json!({"type": "checkerboard", "color0": 0.1, "color1": 5.0});
    let e = parse(json!({"id": "d", "type": "roughdielectric", "alpha": too_rough})).unwrap_err();
    assert_eq!(e.field(), Some("materials[3].alpha"), "{e}");
    let e = parse(json!({"id": "p", "type": "roughplastic", "alpha": checker})).unwrap_err();
    assert_eq!(e.field(), Some("materials[3].alpha"), "{e}");
    assert!(e.to_string().contains("not a texture"), "{e}");
    // A reflectance texture past 1 is refused for that, naming the field.
    let bright = json!({"type": "checkerboard", "color0": 5.0, "color1": 0.4});
    let e = parse(json!({"id": "b", "type": "diffuse", "reflectance": bright})).unwrap_err();
    assert_eq!(e.field(), Some("materials[3].reflectance"), "{e}");
    assert!(
        e.to_string()
            .contains("the texture reaches 5, not an albedo in [0, 1]"),
        "{e}"
    );
}
