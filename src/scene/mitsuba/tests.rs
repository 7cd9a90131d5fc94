//! Mitsuba XML: the bundled Cornell box against its JSON twin, every
//! supported element, every error path, and a property test that random and
//! mutated input never panics.

use crate::scene::texture::Texture;
use std::path::{Path, PathBuf};

use glam::DVec3;
use proptest::prelude::*;

use crate::scene::emitter::AreaLight;
use crate::scene::emitter::directional::DirectionalLight;
use crate::scene::emitter::point::PointLight;
use crate::scene::emitter::spot::SpotLight;
use crate::scene::material::Distribution;
use crate::scene::material::Interface;
use crate::scene::material::blend::BlendMaterial;
use crate::scene::material::conductor::ConductorMaterial;
use crate::scene::material::dielectric::DielectricMaterial;
use crate::scene::material::diffuse::DiffuseMaterial;
use crate::scene::material::plastic::PlasticMaterial;
use crate::scene::material::rough_conductor::RoughConductorMaterial;
use crate::scene::material::rough_plastic::RoughPlasticMaterial;
use crate::scene::material::twosided::TwoSidedMaterial;
use crate::scene::{Emitter, Environment, Material, PixelFilter, Scene, SceneError};

use super::{MitsubaOptions, Warnings};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// A scratch directory for files a test writes, removed on drop.
struct Scratch(PathBuf);

impl Scratch {
    fn new(tag: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!("bmc-mitsuba-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        Scratch(dir)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn options(lenient: bool) -> MitsubaOptions {
    MitsubaOptions {
        lenient,
        ..Default::default()
    }
}

fn load_in(text: &str, dir: &Path, lenient: bool) -> Result<(Scene, Warnings), SceneError> {
    Scene::from_mitsuba_xml_str(text, dir, dir, &options(lenient))
}

fn load(text: &str) -> Result<(Scene, Warnings), SceneError> {
    load_in(text, &scenes_dir(), false)
}

/// A scene with a camera and a white BSDF `w` around `body`.
fn wrap(body: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
  <bsdf type="diffuse" id="w"><rgb name="reflectance" value="0.5"/></bsdf>
{body}
</scene>"#
    )
}

fn load_err(text: &str) -> SceneError {
    match load(text) {
        Ok(_) => panic!("expected an error for {text}"),
        Err(e) => e,
    }
}

fn ok(body: &str) -> Scene {
    load(&wrap(body)).unwrap_or_else(|e| panic!("{e}")).0
}

fn err(body: &str) -> String {
    load_err(&wrap(body)).to_string()
}

/// Line (1-based) of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

fn syntax_line(e: &SceneError) -> usize {
    match e {
        SceneError::Syntax { line, .. } => *line,
        other => panic!("expected a located error, got {other}"),
    }
}

#[test]
fn cornell_box_xml_equals_json() {
    let dir = scenes_dir();
    let json = Scene::load(&dir.join("cornell-box.json"), &dir).unwrap();
    let xml = Scene::load(&dir.join("cornell-box.xml"), &dir).unwrap();
    let (_, warnings) = Scene::load_mitsuba_xml(
        &dir.join("cornell-box.xml"),
        &dir,
        &MitsubaOptions::default(),
    )
    .unwrap();
    // Its film's Gaussian filter is read as Mitsuba has it; the JSON
    // file's camera has the default box, and the cameras differ only there.
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(xml.camera.filter(), PixelFilter::Gaussian { stddev: 0.5 });
    assert_eq!(json.camera.filter(), PixelFilter::Box);
    assert_eq!(xml.name, json.name);
    assert_eq!(xml.materials, json.materials);
    assert_eq!(xml.material_ids, json.material_ids);
    assert_eq!(xml.emitters, json.emitters);
    assert!(xml.environment.is_none() && json.environment.is_none());
    // Debug prints every f64 exactly (shortest round-trip form).
    assert_eq!(
        format!("{:?}", xml.camera).replace("Gaussian { stddev: 0.5 }", "Box"),
        format!("{:?}", json.camera)
    );
    assert_eq!(
        format!("{:?}", xml.triangles),
        format!("{:?}", json.triangles)
    );
    assert_eq!(format!("{:?}", xml.shapes), format!("{:?}", json.shapes));
    assert_eq!(xml.triangle_count(), 36);
}

#[test]
fn cornell_box_traces_identically() {
    let dir = scenes_dir();
    let json = Scene::load(&dir.join("cornell-box.json"), &dir).unwrap();
    let xml = Scene::load(&dir.join("cornell-box.xml"), &dir).unwrap();
    for py in 0..16 {
        for px in 0..16 {
            let ray = json
                .camera
                .generate_ray(px as f64 * 16.0 + 0.5, py as f64 * 16.0 + 0.5);
            assert_eq!(xml.intersect(&ray), json.intersect(&ray));
        }
    }
}

#[test]
fn transform_operations_apply_in_document_order() {
    let scene = ok(r#"<shape type="cube"><ref id="w"/>
      <transform name="to_world">
        <scale value="0.5"/>
        <rotate z="1" angle="90"/>
        <translate x="1" y="2" z="3"/>
      </transform></shape>"#);
    let (lo, hi) = scene.bounds();
    let close = |a: DVec3, b: DVec3| (a - b).abs().max_element() < 1e-12;
    assert!(close(lo, DVec3::new(0.5, 1.5, 2.5)), "{lo}");
    assert!(close(hi, DVec3::new(1.5, 2.5, 3.5)), "{hi}");
    // The same through `value` syntax, a 3×3 matrix and per-axis scale.
    let alt = ok(r#"<shape type="cube"><ref id="w"/>
      <transform name="to_world">
        <scale x="0.5" y="0.5" z="0.5"/>
        <matrix value="0 -1 0  1 0 0  0 0 1"/>
        <translate value="1 2 3"/>
      </transform></shape>"#);
    let (lo2, hi2) = alt.bounds();
    assert!(close(lo, lo2) && close(hi, hi2));
}

#[test]
fn lookat_camera_matches_json_look_at() {
    let xml = ok("");
    let json = Scene::from_json_str(
        r#"{"materials": [{"id": "w", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
            "shapes": [], "camera": {"fov": 40, "width": 8, "height": 8,
            "to_world": {"look_at": {"origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}}}}"#,
        &scenes_dir(),
        &scenes_dir(),
    )
    .unwrap();
    assert_eq!(
        format!("{:?}", xml.camera).replace("Gaussian { stddev: 0.5 }", "Box"),
        format!("{:?}", json.camera)
    );
}

/// A `<lookat>` without `up`, or with a zero one, takes Mitsuba 3's: the
/// first tangent of `coordinate_system(normalize(target − origin))`, which
/// is (1, 0, 0) for a view along −z; checked against the explicit `up` it
/// stands for, along −z and along a slanted direction.
#[test]
fn lookat_without_up_takes_mitsubas() {
    let camera = |lookat: &str| {
        let text = format!(
            r#"<scene version="3.0.0"><bsdf type="diffuse" id="w"/>
               <sensor type="perspective"><float name="fov" value="40"/>
               <transform name="to_world">{lookat}</transform>
               <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
               </sensor></scene>"#
        );
        let (scene, _) = load_in(&text, &scenes_dir(), false).unwrap_or_else(|e| panic!("{e}"));
        format!("{:?}", scene.camera)
    };
    let down = camera(r#"<lookat origin="0, 0, 5" target="0, 0, 0"/>"#);
    assert_eq!(
        down,
        camera(r#"<lookat origin="0, 0, 5" target="0, 0, 0" up="0 0 0"/>"#)
    );
    assert_eq!(
        down,
        camera(r#"<lookat origin="0, 0, 5" target="0, 0, 0" up="1, 0, 0"/>"#)
    );
    let n = DVec3::new(1.0, 2.0, -2.0).normalize();
    let s = crate::sphere::Frame::from_normal(n).s;
    let slanted = camera(r#"<lookat origin="0, 0, 0" target="1, 2, -2"/>"#);
    let explicit = format!(
        r#"<lookat origin="0, 0, 0" target="1, 2, -2" up="{}, {}, {}"/>"#,
        s.x, s.y, s.z
    );
    assert_eq!(slanted, camera(&explicit));
    // A view of zero length stays refused.
    let same = r#"<lookat origin="1, 1, 1" target="1, 1, 1"/>"#;
    let text = format!(
        r#"<scene version="3.0.0"><sensor type="perspective"><transform name="to_world">{same}</transform></sensor></scene>"#
    );
    assert!(load_in(&text, &scenes_dir(), false).is_err());
}

#[test]
fn analytic_shapes_and_flip_normals() {
    let scene = ok(r#"
      <shape type="sphere"><point name="center" x="0" y="0" z="-3"/><float name="radius" value="2"/><ref id="w"/></shape>
      <shape type="disk"><boolean name="flip_normals" value="true"/><ref id="w"/>
        <transform name="to_world"><translate z="1"/></transform></shape>
      <shape type="rectangle"><ref id="w"/></shape>"#);
    assert_eq!(scene.shape_count(), 3);
    assert!((scene.shape_area(0) - 16.0 * std::f64::consts::PI).abs() < 1e-9);
    let down = crate::scene::Ray {
        origin: DVec3::new(0.0, 0.0, 4.0),
        dir: DVec3::NEG_Z,
        t_max: f64::INFINITY,
    };
    let hit = scene.intersect(&down).unwrap();
    assert_eq!(hit.shape, 1);
    assert!((hit.t - 3.0).abs() < 1e-9);
    // The disk's front turned to -z: its flip flag is recorded.
    assert!(scene.shapes[1].flip);
}

#[test]
fn shapes_without_bsdf_get_mitsubas_default_diffuse() {
    let scene = ok(r#"<shape type="rectangle"/>"#);
    let m = scene.shape_material(0);
    assert_eq!(
        scene.materials[m],
        Material::Diffuse(DiffuseMaterial {
            reflectance: Texture::from([0.5; 3])
        })
    );
    assert_eq!(scene.material_ids[m], "default-diffuse@mitsuba");
}

#[test]
fn bsdf_mappings() {
    let scene = ok(r#"
      <bsdf type="twosided" id="two"><bsdf type="diffuse"><float name="reflectance" value="0.25"/></bsdf></bsdf>
      <bsdf type="plastic" id="plastic">
        <rgb name="diffuse_reflectance" value="0.6 0.4 0.2"/><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/>
      </bsdf>
      <bsdf type="roughplastic" id="rough"><float name="alpha" value="0.1"/><string name="distribution" value="GGX"/></bsdf>
      <bsdf type="conductor" id="mirror"/>
      <bsdf type="roughconductor" id="metal">
        <float name="alpha_u" value="0.5"/><float name="alpha_v" value="0.2"/><rgb name="eta" value="0.2 0.2 0.2"/><rgb name="k" value="3 3 3"/>
      </bsdf>
      <bsdf type="conductor" id="gold"><string name="material" value="Au"/></bsdf>
      <bsdf type="dielectric" id="water"><string name="int_ior" value="water"/></bsdf>
      <bsdf type="thindielectric" id="pane"/>
      <bsdf type="roughdielectric" id="frosted"><float name="alpha" value="0.3"/></bsdf>"#);
    let by_id = |id: &str| {
        let i = scene.material_ids.iter().position(|m| m == id).unwrap();
        scene.materials[i].clone()
    };
    let grey = Material::Diffuse(DiffuseMaterial {
        reflectance: Texture::from([0.25; 3]),
    });
    assert_eq!(
        by_id("two"),
        Material::TwoSided(TwoSidedMaterial {
            front: std::sync::Arc::new(grey.clone()),
            back: std::sync::Arc::new(grey)
        })
    );
    assert_eq!(
        by_id("plastic"),
        Material::Plastic(PlasticMaterial {
            diffuse_reflectance: Texture::from([0.6, 0.4, 0.2]),
            specular_reflectance: Texture::from([1.0; 3]),
            eta: 1.5,
            nonlinear: false,
        })
    );
    let Material::RoughPlastic(RoughPlasticMaterial { eta, roughness, .. }) = by_id("rough") else {
        panic!("{:?}", by_id("rough"))
    };
    assert!((eta - 1.49 / 1.000277).abs() < 1e-12, "Mitsuba's defaults");
    assert_eq!(roughness.distribution, Distribution::Ggx);
    assert_eq!((roughness.alpha_u, roughness.alpha_v), (0.1, 0.1));
    assert_eq!(
        by_id("mirror"),
        Material::Conductor(ConductorMaterial {
            eta: [0.0; 3],
            k: [1.0; 3],
            specular_reflectance: Texture::from([1.0; 3]),
        })
    );
    let Material::RoughConductor(RoughConductorMaterial {
        eta, k, roughness, ..
    }) = by_id("metal")
    else {
        panic!()
    };
    assert_eq!((eta, k), ([0.2; 3], [3.0; 3]));
    assert_eq!(
        roughness.distribution,
        Distribution::Beckmann,
        "Mitsuba's default"
    );
    assert_eq!((roughness.alpha_u, roughness.alpha_v), (0.5, 0.2));
    let Material::Conductor(ConductorMaterial { eta, .. }) = by_id("gold") else {
        panic!()
    };
    assert!(eta[0] < eta[2], "gold: {eta:?}");
    let Material::Dielectric(DielectricMaterial(Interface { eta, .. })) = by_id("water") else {
        panic!()
    };
    assert!((eta - 1.333 / 1.000277).abs() < 1e-12);
    assert!(matches!(by_id("pane"), Material::ThinDielectric(_)));
    assert!(matches!(by_id("frosted"), Material::RoughDielectric(_)));
}

#[test]
fn bad_bsdf_parameters_point_at_their_element() {
    for (body, needle, words) in [
        (
            r#"<bsdf type="dielectric"><string name="int_ior" value="unobtainium"/></bsdf>"#,
            "unobtainium",
            "unknown medium",
        ),
        (
            r#"<bsdf type="conductor"><string name="material" value="Xx"/></bsdf>"#,
            "Xx",
            "unknown metal",
        ),
        (
            r#"<bsdf type="roughconductor"><float name="alpha" value="-1"/></bsdf>"#,
            "alpha",
            "not a roughness",
        ),
        (
            r#"<bsdf type="plastic"><rgb name="diffuse_reflectance" value="2"/></bsdf>"#,
            "diffuse_reflectance",
            "not an albedo",
        ),
        (
            r#"<bsdf type="twosided"><bsdf type="dielectric"/></bsdf>"#,
            "\"dielectric\"/></bsdf>",
            "cannot be one side",
        ),
    ] {
        let text = wrap(body);
        let e = load_err(&text);
        assert_eq!(syntax_line(&e), line_of(&text, needle), "{e}");
        assert!(e.to_string().contains(words), "{e}");
    }
}

#[test]
fn emitters_area_constant_envmap_and_point() {
    let scene = ok(r#"
      <shape type="rectangle"><ref id="w"/><emitter type="area"><rgb name="radiance" value="1 2 3"/></emitter></shape>
      <emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>"#);
    assert_eq!(
        scene.emitters,
        vec![Emitter::Area(AreaLight {
            shape: 0,
            radiance: Texture::Constant([1.0, 2.0, 3.0])
        })]
    );
    assert!(matches!(
        scene.environment,
        Some(Environment::Constant {
            radiance: [0.1, 0.1, 0.1]
        })
    ));

    let scene = ok(
        r#"<emitter type="envmap"><string name="filename" value="sky.exr"/><float name="scale" value="2"/>
        <transform name="to_world"><rotate y="1" angle="90"/></transform></emitter>"#,
    );
    let Some(Environment::Map(map)) = &scene.environment else {
        panic!("envmap expected")
    };
    let direct = Scene::from_json_str(
        r#"{"shapes": [], "camera": {"fov": 40, "width": 8, "height": 8, "origin": [0,0,5], "target": [0,0,0], "up": [0,1,0]},
            "environment": {"type": "envmap", "filename": "sky.exr", "scale": 2,
            "to_world": {"rotate": {"axis": [0, 1, 0], "angle": 90}}}}"#,
        &scenes_dir(),
        &scenes_dir(),
    )
    .unwrap();
    let Some(Environment::Map(expected)) = &direct.environment else {
        panic!()
    };
    assert_eq!(format!("{map:?}"), format!("{expected:?}"));

    let (scene, warnings) = load(&wrap(
        r#"<emitter type="point"><point name="position" value="0 1 0"/><rgb name="intensity" value="2"/></emitter>
           <emitter type="spot"><transform name="to_world"><lookat origin="0 2 0" target="0 0 0" up="0 0 1"/></transform>
             <float name="cutoff_angle" value="30"/></emitter>
           <emitter type="directional"><vector name="direction" value="0 -2 0"/><rgb name="irradiance" value="3"/></emitter>"#,
    ))
    .unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(
        scene.emitters,
        vec![
            Emitter::Point(PointLight {
                position: [0.0, 1.0, 0.0],
                intensity: [2.0; 3]
            }),
            Emitter::Spot(SpotLight {
                position: [0.0, 2.0, 0.0],
                direction: [0.0, -1.0, 0.0],
                intensity: [1.0; 3],
                cutoff_angle: 30f64.to_radians(),
                beam_width: 22.5f64.to_radians(),
            }),
            Emitter::Directional(DirectionalLight {
                direction: [0.0, -1.0, 0.0],
                irradiance: [3.0; 3]
            }),
        ]
    );
}

#[test]
fn spectra_read_as_mitsubas_rgb_variants_read_them() {
    // A one-valued spectrum on an emitter is the equal-energy white.
    let white = [1.204794, 0.948291, 0.908916];
    let scene = ok(r#"
      <shape type="rectangle"><ref id="w"/><emitter type="area"><spectrum name="radiance" value="2"/></emitter></shape>
      <emitter type="constant"><spectrum name="radiance" value="1"/></emitter>"#);
    let [
        Emitter::Area(AreaLight {
            radiance: Texture::Constant(radiance),
            ..
        }),
    ] = scene.emitters[..]
    else {
        panic!("{:?}", scene.emitters)
    };
    let Some(Environment::Constant { radiance: sky }) = scene.environment else {
        panic!()
    };
    for c in 0..3 {
        assert!((radiance[c] - 2.0 * white[c]).abs() < 1e-5, "{radiance:?}");
        assert!((sky[c] - white[c]).abs() < 1e-5, "{sky:?}");
    }

    // A spectrum file is resolved beside the scene and read once.
    let dir = Scratch::new("spectra");
    std::fs::write(dir.0.join("flat.spd"), "# flat\n360 1\n830 1\n").unwrap();
    std::fs::write(dir.0.join("bad.spd"), "400 0.5\n500 half\n").unwrap();
    let light = |spectrum: &str| {
        wrap(&format!(
            r#"<emitter type="point"><point name="position" value="0 1 0"/>{spectrum}</emitter>"#
        ))
    };
    let (scene, _) = load_in(
        &light(r#"<spectrum name="intensity" filename="flat.spd"/>"#),
        &dir.0,
        false,
    )
    .unwrap();
    let Emitter::Point(PointLight { intensity, .. }) = scene.emitters[0] else {
        panic!()
    };
    // Mitsuba 3.9.1: spectrum_list_to_srgb([360, 830], [1, 1], false, false).
    let flat = [1.20488, 0.948229, 0.909267];
    for c in 0..3 {
        assert!((intensity[c] - flat[c]).abs() < 2e-5, "{intensity:?}");
    }

    // `uniform` spectra and `rawconstant` textures are their values as they
    // are, with no white point on an emitter.
    for (given, expected) in [
        (
            r#"<spectrum name="intensity" type="uniform"><float name="value" value="2"/></spectrum>"#,
            [2.0; 3],
        ),
        (
            r#"<texture name="intensity" type="rawconstant"><vector name="value" value="1, 2, 3"/></texture>"#,
            [1.0, 2.0, 3.0],
        ),
    ] {
        let (scene, _) = load_in(&light(given), &dir.0, false).unwrap();
        let Emitter::Point(PointLight { intensity, .. }) = scene.emitters[0] else {
            panic!()
        };
        assert_eq!(intensity, expected, "{given}");
    }

    // Malformed spectra are refused naming the attribute and the problem.
    for (spectrum, says) in [
        (
            r#"<spectrum name="intensity" value="1" filename="flat.spd"/>"#,
            "exactly one",
        ),
        (
            r#"<spectrum name="intensity" filename="missing.spd"/>"#,
            "filename",
        ),
        (
            r#"<spectrum name="intensity" filename="bad.spd"/>"#,
            "line 2",
        ),
        (
            r#"<spectrum name="intensity" filename="../outside.spd"/>"#,
            "filename",
        ),
        (
            r#"<spectrum name="intensity" value="500:1, 400:2"/>"#,
            "must increase",
        ),
        (
            r#"<spectrum name="intensity" type="blackbody"/>"#,
            "blackbody",
        ),
    ] {
        let e = load_in(&light(spectrum), &dir.0, false)
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(says), "{spectrum}: {e}");
    }
}

#[test]
fn sensor_fov_axes_and_focal_length() {
    let cam = |sensor: &str| {
        let text = format!(
            r#"<scene version="3.0.0"><sensor type="perspective">{sensor}
                 <film type="hdrfilm"><integer name="width" value="30"/><integer name="height" value="20"/></film>
               </sensor></scene>"#
        );
        load(&text).unwrap_or_else(|e| panic!("{e}")).0.camera
    };
    // Looking along +z: the image centre ray goes straight ahead.
    let c = cam(r#"<float name="fov" value="60"/><string name="fov_axis" value="y"/>"#);
    assert_eq!(c.resolution(), (30, 20));
    let top = c.generate_ray(15.0, 0.0).dir;
    assert!((top.y.atan2(top.z).to_degrees() - 30.0).abs() < 1e-9);
    let d = cam(r#"<float name="fov" value="60"/><string name="fov_axis" value="diagonal"/>"#);
    let corner = d.generate_ray(0.0, 0.0).dir;
    assert!((corner.angle_between(DVec3::Z).to_degrees() - 30.0).abs() < 1e-9);
    let f = cam(r#"<string name="focal_length" value="50mm"/>"#);
    let corner = f.generate_ray(0.0, 0.0).dir;
    let half_diagonal = (43.266615305567875f64 / 100.0).atan().to_degrees();
    assert!((corner.angle_between(DVec3::Z).to_degrees() - half_diagonal).abs() < 1e-9);
}

#[test]
fn reconstruction_filters_as_mitsuba_reads_them() {
    let filter = |film: &str| {
        let text = format!(
            r#"<scene version="3.0.0"><sensor type="perspective">
                 <film type="hdrfilm"><integer name="width" value="30"/><integer name="height" value="20"/>{film}</film>
               </sensor></scene>"#
        );
        let (scene, warnings) = load(&text).unwrap_or_else(|e| panic!("{e}"));
        (scene.camera.filter(), warnings.len())
    };
    // Mitsuba's films filter with a Gaussian of σ = 0.5 unless told otherwise.
    assert_eq!(filter(""), (PixelFilter::Gaussian { stddev: 0.5 }, 0));
    assert_eq!(
        filter(r#"<rfilter type="gaussian"><float name="stddev" value="0.8"/></rfilter>"#),
        (PixelFilter::Gaussian { stddev: 0.8 }, 0)
    );
    assert_eq!(
        filter(r#"<rfilter type="tent"/>"#),
        (PixelFilter::Tent { radius: 1.0 }, 0)
    );
    assert_eq!(filter(r#"<rfilter type="box"/>"#), (PixelFilter::Box, 0));
    // Filters with negative lobes, and a box wider than a pixel, are
    // approximated by the pixel's box, said once each.
    assert_eq!(
        filter(r#"<rfilter type="mitchell"/>"#),
        (PixelFilter::Box, 1)
    );
    assert_eq!(
        filter(r#"<rfilter type="box"><float name="radius" value="1"/></rfilter>"#),
        (PixelFilter::Box, 1)
    );
    // A width the filter cannot have names its field.
    let e = load_err(
        r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm">
             <rfilter type="gaussian"><float name="stddev" value="-1"/></rfilter></film></sensor></scene>"#,
    );
    assert!(e.to_string().contains("camera.filter.stddev"), "{e}");
}

#[test]
fn parameters_override_defaults() {
    let text = r#"<scene version="3.0.0"><default name="res" value="8"/>
      <sensor type="perspective"><float name="fov" value="40"/>
        <film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="$res"/></film></sensor></scene>"#;
    assert_eq!(load(text).unwrap().0.camera.resolution(), (8, 8));
    let mut opts = MitsubaOptions::default();
    opts.parameters.insert("res".into(), "16".into());
    let scene = Scene::from_mitsuba_xml_str(text, &scenes_dir(), &scenes_dir(), &opts)
        .unwrap()
        .0;
    assert_eq!(scene.camera.resolution(), (16, 16));
}

fn write_ply_ascii(path: &Path) {
    std::fs::write(
        path,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
    )
    .unwrap();
}

fn write_ply_binary(path: &Path) {
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\n\
        property double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\n\
        element face 1\nproperty list uchar uint vertex_indices\nend_header\n"
        .to_vec();
    for p in [[0.0f64, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]] {
        for x in p {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
        for n in [0.0f32, 0.0, 1.0] {
            bytes.extend_from_slice(&n.to_le_bytes());
        }
    }
    bytes.push(3);
    for i in [0u32, 1, 2] {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn meshes_from_obj_and_ply() {
    let dir = Scratch::new("meshes");
    write_ply_ascii(&dir.0.join("quad.ply"));
    write_ply_binary(&dir.0.join("sub/tri.ply"));
    std::fs::write(
        dir.0.join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let text = wrap(
        r#"<shape type="ply"><string name="filename" value="quad.ply"/><ref id="w"/></shape>
           <shape type="ply"><string name="filename" value="sub/tri.ply"/><ref id="w"/></shape>
           <shape type="obj"><string name="filename" value="tri.obj"/><ref id="w"/></shape>
           <shape type="obj"><string name="filename" value="tri.obj"/><boolean name="face_normals" value="true"/><ref id="w"/></shape>"#,
    );
    let (scene, _) = load_in(&text, &dir.0, false).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.triangle_count(), 2 + 1 + 1 + 1);
    assert!((scene.shape_area(0) - 1.0).abs() < 1e-12);
    assert!((scene.shape_area(1) - 2.0).abs() < 1e-12);
    assert!((scene.shape_area(2) - 0.5).abs() < 1e-12);
    // The binary PLY's vertex normals are kept; the meshes without them get
    // smooth ones (Mitsuba's default) except the one with `face_normals`.
    assert_eq!(scene.vertex_normals.len(), 2 + 1 + 1);
}

#[test]
fn meshes_of_a_serialized_file() {
    let dir = Scratch::new("serialized");
    let data =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/two_meshes.serialized");
    std::fs::copy(data, dir.0.join("two.serialized")).unwrap();
    let shape = |extra: &str| {
        format!(
            r#"<shape type="serialized"><string name="filename" value="two.serialized"/>{extra}<ref id="w"/></shape>"#
        )
    };
    let text = wrap(
        &[
            shape(""),
            shape(r#"<integer name="shape_index" value="1"/>"#),
        ]
        .concat(),
    );
    let (scene, _) = load_in(&text, &dir.0, false).unwrap_or_else(|e| panic!("{e}"));
    // The quad (two triangles, area 1) and the triangle, read from one file.
    assert_eq!(scene.triangle_count(), 3);
    assert!((scene.shape_area(0) - 1.0).abs() < 1e-12);
    let Err(e) = load_in(
        &wrap(&shape(r#"<integer name="shape_index" value="5"/>"#)),
        &dir.0,
        false,
    ) else {
        panic!("a missing mesh loaded");
    };
    assert!(e.to_string().contains("holds 2 meshes"), "{e}");
    let Err(e) = load_in(
        &wrap(&shape(r#"<integer name="shape_index" value="-1"/>"#)),
        &dir.0,
        false,
    ) else {
        panic!("a negative index loaded");
    };
    assert!(e.to_string().contains("outside"), "{e}");
}

#[test]
fn instances_of_a_shapegroup() {
    let scene = ok(r#"
      <shape type="shapegroup" id="g">
        <shape type="rectangle"><ref id="w"/><transform name="to_world"><scale value="0.5"/></transform></shape>
      </shape>
      <shape type="instance"><ref id="g"/><transform name="to_world"><translate x="3"/></transform></shape>
      <shape type="instance"><ref id="g"/><transform name="to_world"><translate x="-3"/></transform></shape>"#);
    assert_eq!(scene.shape_count(), 2);
    let (lo, hi) = scene.bounds();
    assert!((lo.x + 3.5).abs() < 1e-12 && (hi.x - 3.5).abs() < 1e-12);
}

#[test]
fn textures_become_texture_documents_or_lenient_means() {
    // A checkerboard on a reflectance is the scene model's checkerboard.
    let scene = ok(
        r#"<bsdf type="diffuse" id="t"><texture type="checkerboard" name="reflectance">
        <rgb name="color0" value="0.8"/><rgb name="color1" value="0.2"/>
        <transform name="to_uv"><scale x="4" y="2"/></transform></texture></bsdf>"#,
    );
    let i = scene.material_ids.iter().position(|m| m == "t").unwrap();
    let Material::Diffuse(DiffuseMaterial {
        reflectance: Texture::Checkerboard(board),
    }) = &scene.materials[i]
    else {
        panic!("{:?}", scene.materials[i])
    };
    assert_eq!((board.color0, board.color1), ([0.8; 3], [0.2; 3]));
    assert_eq!(board.to_uv.matrix2.x_axis.x, 4.0);

    // A texture where the model takes a constant (a rough plastic's roughness),
    // and a texture type it lacks: errors, or with lenient their means.
    // (A rough conductor takes the same map as a texture.)
    let scene = ok(
        r#"<bsdf type="roughconductor" id="t"><texture type="checkerboard" name="alpha">
            <float name="color0" value="0.3"/><float name="color1" value="0.1"/></texture></bsdf>
            <shape type="rectangle"><ref id="t"/></shape>"#,
    );
    assert!(scene.materials.iter().any(|m| matches!(m,
        Material::RoughConductor(RoughConductorMaterial { roughness: r, .. }) if r.textures.is_some())));
    for (body, what) in [
        (
            r#"<bsdf type="roughplastic" id="t"><texture type="checkerboard" name="alpha">
            <float name="color0" value="0.3"/><float name="color1" value="0.1"/></texture></bsdf>
            <shape type="rectangle"><ref id="t"/></shape>"#,
            "alpha",
        ),
        (
            r#"<bsdf type="diffuse" id="t"><texture type="gridvolume" name="reflectance"/></bsdf>
            <shape type="rectangle"><ref id="t"/></shape>"#,
            "gridvolume",
        ),
    ] {
        let e = err(body);
        assert!(e.contains(what) && e.contains("lenient"), "{e}");
        let (scene, warnings) = load_in(&wrap(body), &scenes_dir(), true).unwrap();
        assert!(
            warnings.iter().any(|w| w.message.contains(what)),
            "{warnings:?}"
        );
        let i = scene.material_ids.iter().position(|m| m == "t").unwrap();
        match &scene.materials[i] {
            Material::RoughPlastic(RoughPlasticMaterial { roughness: r, .. }) => {
                assert!((r.alpha_u - 0.2).abs() < 1e-12, "{r:?}")
            }
            Material::Diffuse(DiffuseMaterial { reflectance }) => {
                assert_eq!(*reflectance, Texture::from([0.5; 3]))
            }
            other => panic!("{other:?}"),
        }
    }

    // sRGB 255 and 0 are linear 1 and 0; sRGB 188 is linear ≈ 0.5029.
    let dir = Scratch::new("bitmap");
    image::RgbImage::from_raw(2, 1, vec![255, 255, 188, 0, 0, 188])
        .unwrap()
        .save(dir.0.join("tex.png"))
        .unwrap();
    let bitmap = r#"<bsdf type="diffuse" id="t"><texture type="bitmap" name="reflectance">
        <string name="filename" value="tex.png"/>
        <string name="filter_type" value="nearest"/></texture></bsdf>"#;
    let (scene, warnings) = load_in(&wrap(bitmap), &dir.0, false).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    let i = scene.material_ids.iter().position(|m| m == "t").unwrap();
    let Material::Diffuse(DiffuseMaterial { reflectance }) = &scene.materials[i] else {
        panic!()
    };
    let left = reflectance.eval(glam::DVec2::new(0.25, 0.5));
    let right = reflectance.eval(glam::DVec2::new(0.75, 0.5));
    assert!(
        (left[0] - 1.0).abs() < 1e-6 && (right[0]).abs() < 1e-6,
        "{left:?} {right:?}"
    );
    assert!((left[2] - 0.502886).abs() < 1e-5, "{left:?}");
}

#[test]
fn unknown_plugin_names_plugin_and_line() {
    let text = wrap(
        r#"<bsdf type="pplastic" id="fancy"/><shape type="rectangle"><ref id="fancy"/></shape>"#,
    );
    let e = load_err(&text);
    assert_eq!(syntax_line(&e), line_of(&text, "pplastic"));
    assert!(e.to_string().contains("\"pplastic\""), "{e}");
    let (_, warnings) = load_in(&text, &scenes_dir(), true).unwrap();
    assert!(warnings[0].message.contains("pplastic"));

    let e = err(r#"<shape type="ellipsoids"/>"#);
    assert!(e.contains("ellipsoids"), "{e}");
    let e = err(r#"<shape type="disk"><sensor type="radiancemeter"/></shape>"#);
    assert!(e.contains("radiancemeter"), "{e}");
    for medium in [
        r#"<shape type="sphere"><medium type="homogeneous" name="interior"/></shape>"#,
        r#"<medium type="heterogeneous" id="fog"/>"#,
    ] {
        let e = err(medium);
        assert!(e.contains("participating media are not supported"), "{e}");
        let (_, warnings) = load_in(&wrap(medium), &scenes_dir(), true).unwrap();
        assert!(
            warnings.iter().any(|w| w.message.contains("vacuum")),
            "{warnings:?}"
        );
    }
    let e = err(r#"<emitter type="projector"/>"#);
    assert!(e.contains("projector"), "{e}");
    let text = wrap(r#"<bsdf type="diffuse"><float name="roughness" value="1"/></bsdf>"#);
    let e = load_err(&text).to_string();
    assert!(e.contains("roughness"), "{e}");
    let (_, warnings) = load_in(&text, &scenes_dir(), true).unwrap();
    assert!(
        warnings.iter().any(|w| w.message.contains("roughness")),
        "{warnings:?}"
    );
    let e = err(r#"<shape type="rectangle"><emitter type="envmap"/></shape>"#);
    assert!(e.contains("only `area`"), "{e}");
}

#[test]
fn bad_transforms_are_located() {
    let text = wrap(
        "<shape type=\"cube\"><ref id=\"w\"/><transform name=\"to_world\">\n<shear value=\"1\"/>\n</transform></shape>",
    );
    let e = load_err(&text);
    assert_eq!(syntax_line(&e), line_of(&text, "shear"));
    assert!(e.to_string().contains("not a transform operation"), "{e}");
    assert!(err(r#"<shape type="cube"><transform name="to_world"><matrix value="1 2 3"/></transform></shape>"#)
        .contains("16"));
    assert!(err(r#"<shape type="cube"><transform name="to_world"><rotate angle="30"/></transform></shape>"#)
        .contains("zero length"));
    assert!(err(r#"<shape type="cube"><transform name="to_world"><scale value="0"/></transform></shape>"#)
        .contains("singular"));
    assert!(err(r#"<shape type="cube"><transform name="to_world"><translate x="nan"/></transform></shape>"#)
        .contains("finite"));
}

#[test]
fn huge_numbers_are_rejected_at_their_line() {
    let text = wrap(
        "<shape type=\"cube\"><ref id=\"w\"/><transform name=\"to_world\">\n<translate x=\"1\"/>\n<scale value=\"1e300\"/>\n</transform></shape>",
    );
    let e = load_err(&text);
    assert_eq!(syntax_line(&e), line_of(&text, "1e300"));
    assert!(
        e.to_string().contains("1e300") || e.to_string().contains("magnitude"),
        "{e}"
    );
    let e = err(
        r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1e300"/></emitter></shape>"#,
    );
    assert!(e.contains("radiance"), "{e}");
    let e = err(
        r#"<shape type="cube"><transform name="to_world"><scale value="1e999"/></transform></shape>"#,
    );
    assert!(e.contains("finite"), "{e}");
}

#[test]
fn missing_and_escaping_files() {
    let e = err(r#"<shape type="obj"><string name="filename" value="nope.obj"/></shape>"#);
    assert!(e.contains("nope.obj"), "{e}");
    let e = load_err(&wrap(
        r#"<shape type="ply"><string name="filename" value="nope.ply"/></shape>"#,
    ));
    // Read by the shared loader, located at the element that names it.
    let text = e.to_string();
    assert!(
        text.contains(":8: <shape type=\"ply\"> (shapes[0].filename)") && text.contains("nope.ply"),
        "{e}"
    );
    for body in [
        r#"<shape type="ply"><string name="filename" value="../Cargo.toml"/></shape>"#,
        r#"<shape type="obj"><string name="filename" value="../../etc/passwd"/></shape>"#,
        r#"<emitter type="envmap"><string name="filename" value="../sky.exr"/></emitter>"#,
    ] {
        let e = load_err(&wrap(body));
        assert!(matches!(e, SceneError::PathEscape { .. }), "{body}: {e}");
    }
    let e = load_err(&wrap(
        r#"<emitter type="envmap"><string name="filename" value="mesh.json"/></emitter>"#,
    ));
    assert!(matches!(e, SceneError::File { .. }), "{e}");
}

#[test]
fn reference_errors() {
    let e = err(r#"<bsdf type="twosided" id="a"><ref id="b"/></bsdf>
           <bsdf type="twosided" id="b"><ref id="a"/></bsdf>"#);
    assert!(e.contains("cycle"), "{e}");
    let e = err(
        r#"<texture type="checkerboard" id="t"><ref name="color0" id="t"/></texture>
           <bsdf type="diffuse"><ref name="reflectance" id="t"/></bsdf>"#,
    );
    assert!(e.contains("cycle"), "{e}");
    // A long chain of references, each naming one declared after it, is
    // capped like deep nesting; declared the other way round, each is read
    // once and named, and the chain's plugins are counted.
    let chain: Vec<String> = (0..1000)
        .map(|i| {
            format!(
                r#"<bsdf type="mask" id="c{i}"><ref id="c{}"/></bsdf>"#,
                i + 1
            )
        })
        .chain(std::iter::once(
            r#"<bsdf type="diffuse" id="c1000"/>"#.to_string(),
        ))
        .collect();
    let e = err(&(chain.concat() + r#"<shape type="rectangle"><ref id="c0"/></shape>"#));
    assert!(e.contains("deeper than"), "{e}");
    let bottom_up: String = chain.iter().rev().map(String::as_str).collect();
    let e = err(&(bottom_up + r#"<shape type="rectangle"><ref id="c0"/></shape>"#));
    assert!(e.contains("MAX_MATERIAL_NODES"), "{e}");
    let e = err(r#"<shape type="rectangle"><ref id="missing"/></shape>"#);
    assert!(e.contains("missing"), "{e}");
    let e = err(r#"<bsdf type="diffuse" id="w"/>"#);
    assert!(e.contains("duplicate id"), "{e}");
    let e = err(r#"<shape type="instance"><ref id="w"/></shape>"#);
    assert!(e.contains("exactly one"), "{e}");
}

#[test]
fn parse_level_errors_carry_lines() {
    let e = load_err("<scene version=\"3.0.0\">\n<shape type=\"cube\">\n</scene>");
    assert_eq!(syntax_line(&e), 3);
    let e = load_err("<scene version=\"3.0.0\">\n<integer name=\"x\" value=\"$spp\"/></scene>");
    assert_eq!(syntax_line(&e), 2);
    assert!(e.to_string().contains("$spp"));
    let deep = format!(
        "<scene version=\"3.0.0\">{}{}</scene>",
        "<shape type=\"shapegroup\">".repeat(200),
        "</shape>".repeat(200)
    );
    assert!(load_err(&deep).to_string().contains("nested deeper"));
    // Mitsuba 0.x documents are upgraded; a version from the future is not read.
    let e = load_err(r#"<scene version="4.0.0"/>"#);
    assert!(e.to_string().contains("4.0.0"), "{e}");
    let e = load_err(r#"<scene/>"#);
    assert!(e.to_string().contains("version"));
    let e = load_err(r#"<scene version="3.0.0"/>"#);
    assert!(e.to_string().contains("no <sensor>"), "{e}");
    assert!(load_in(r#"<scene version="3.0.0"/>"#, &scenes_dir(), true).is_ok());
}

#[test]
fn warnings_are_counted_but_only_the_first_kept() {
    let count = 50_000;
    let text = wrap(&"<foo/>".repeat(count));
    let (_, warnings) = load_in(&text, &scenes_dir(), true).unwrap();
    assert_eq!(warnings.total(), count);
    assert_eq!(warnings.len(), super::MAX_WARNINGS);
    assert!(warnings[0].message.contains("<foo>"), "{}", warnings[0]);
}

/// Writes a `width × height` PNG whose rows repeat the bytes `pixel`, row by
/// row (never the whole image in memory).
fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    pixel: &[u8],
) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut encoder = png::Encoder::new(file, width, height);
    encoder.set_color(color);
    encoder.set_depth(depth);
    if color == png::ColorType::Indexed {
        encoder.set_palette(vec![0, 0, 0, 255, 255, 255]);
    }
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    // `pixel` repeated over the row's bytes (for depths below 8 it holds
    // several pixels per byte).
    let row_bits = width as usize * color.samples() * depth as usize;
    let row: Vec<u8> = pixel
        .iter()
        .copied()
        .cycle()
        .take(row_bits.div_ceil(8))
        .collect();
    for _ in 0..height {
        std::io::Write::write_all(&mut stream, &row).unwrap();
    }
    stream.finish().unwrap();
}

fn bitmap_reflectance(dir: &Path, file: &str) -> Result<[f64; 3], SceneError> {
    let bitmap = format!(
        r#"<bsdf type="diffuse" id="t"><texture type="bitmap" name="reflectance">
        <string name="filename" value="{file}"/><boolean name="raw" value="true"/></texture></bsdf>"#
    );
    let (scene, _) = load_in(&wrap(&bitmap), dir, true)?;
    let i = scene.material_ids.iter().position(|m| m == "t").unwrap();
    let Material::Diffuse(DiffuseMaterial { reflectance }) = &scene.materials[i] else {
        panic!()
    };
    Ok(reflectance.mean())
}

#[test]
fn png_means_of_every_pixel_format() {
    use png::{BitDepth, ColorType};
    let dir = Scratch::new("png-formats");
    let check = |name: &str, color, depth, pixel: &[u8], expected: [f64; 3]| {
        write_png(&dir.0.join(name), 8, 3, color, depth, pixel);
        let got = bitmap_reflectance(&dir.0, name).unwrap();
        for c in 0..3 {
            // Texels are stored as f32.
            assert!((got[c] - expected[c]).abs() < 1e-6, "{name}: {got:?}");
        }
    };
    check(
        "grey.png",
        ColorType::Grayscale,
        BitDepth::Eight,
        &[51],
        [0.2; 3],
    );
    let half = 32768.0 / 65535.0;
    check(
        "grey16.png",
        ColorType::Grayscale,
        BitDepth::Sixteen,
        &[0x80, 0x00],
        [half; 3],
    );
    check(
        "rgba.png",
        ColorType::Rgba,
        BitDepth::Eight,
        &[255, 0, 51, 7],
        [1.0, 0.0, 0.2],
    );
    check(
        "grey-alpha.png",
        ColorType::GrayscaleAlpha,
        BitDepth::Eight,
        &[102, 0],
        [0.4; 3],
    );
    // One-bit palette indices 0b0101_0101: black and white alternate.
    check(
        "palette.png",
        ColorType::Indexed,
        BitDepth::One,
        &[0b0101_0101],
        [0.5; 3],
    );
}

#[test]
fn huge_png_textures_are_refused_from_their_header() {
    let dir = Scratch::new("png-huge");
    // ~260 KB on disk, 256 Mi pixels: refused before any row is decoded.
    write_png(
        &dir.0.join("huge.png"),
        16384,
        16384,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &[0],
    );
    let e = bitmap_reflectance(&dir.0, "huge.png")
        .unwrap_err()
        .to_string();
    assert!(e.contains("16384×16384"), "{e}");
    // Wide but within the pixel budget is fine.
    write_png(
        &dir.0.join("wide.png"),
        8192,
        16,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &[255],
    );
    assert_eq!(bitmap_reflectance(&dir.0, "wide.png").unwrap(), [1.0; 3]);
    // A FIFO is refused without blocking.
    let fifo = dir.0.join("fifo.png");
    if std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        let e = bitmap_reflectance(&dir.0, "fifo.png")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }
}

/// Fragments of the supported vocabulary for random scenes.
const FRAGMENTS: &[&str] = &[
    r#"<shape type="cube"><ref id="w"/></shape>"#,
    r#"<shape type="sphere"><float name="radius" value="0.5"/></shape>"#,
    r#"<shape type="disk"><transform name="to_world"><rotate x="1" angle="45"/></transform></shape>"#,
    r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#,
    r#"<bsdf type="roughplastic"><float name="alpha" value="0.3"/></bsdf>"#,
    r#"<bsdf type="twosided"><ref id="w"/></bsdf>"#,
    r#"<emitter type="constant"/>"#,
    r#"<emitter type="point"/>"#,
    r#"<shape type="ply"><string name="filename" value="x.ply"/></shape>"#,
    r#"<transform name="to_world"><scale value="2"/></transform>"#,
    r#"<ref id="w"/>"#,
    r#"<default name="k" value="1"/>"#,
    r#"<float name="v" value="$k"/>"#,
    r#"<default name="k" value="$k$k$k$k$k$k$k$k$k$k"/>"#,
    r#"<float name="v" value="$k$k$k$k$k$k$k$k$k$k$k$k$k$k$k$k"/>"#,
    "<shape type=\"cube\">",
    "</shape>",
    "<bsdf type=\"twosided\">",
    "</bsdf>",
];

/// Loads `text`; an error must be a short message (values quoted cut), and
/// a success holds no more than the kept warnings.
fn check_no_panic(text: &str, lenient: bool) {
    let dir = scenes_dir();
    match load_in(text, &dir, lenient) {
        Err(e) => {
            let message = e.to_string();
            assert!(!message.is_empty());
            assert!(message.len() < 2048, "{} bytes of message", message.len());
        }
        Ok((_, warnings)) => {
            assert!(warnings.len() <= super::MAX_WARNINGS);
            assert!(warnings.total() >= warnings.len());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        check_no_panic(&String::from_utf8_lossy(&bytes), false);
    }

    #[test]
    fn random_fragment_scenes_never_panic(
        picks in proptest::collection::vec(0..FRAGMENTS.len(), 0..24),
        lenient in any::<bool>(),
    ) {
        let body: String = picks.iter().map(|&i| FRAGMENTS[i]).collect();
        check_no_panic(&wrap(&body), lenient);
    }

    #[test]
    fn random_ply_payloads_never_panic(
        binary in any::<bool>(),
        payload in proptest::collection::vec(any::<u8>(), 0..256),
    ) {
        let dir = Scratch::new("ply-fuzz");
        let format = if binary { "binary_little_endian" } else { "ascii" };
        let mut bytes = format!(
            "ply\nformat {format} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        )
        .into_bytes();
        bytes.extend(payload);
        std::fs::write(dir.0.join("f.ply"), bytes).unwrap();
        let text = wrap(r#"<shape type="ply"><string name="filename" value="f.ply"/></shape>"#);
        if let Err(e) = load_in(&text, &dir.0, false) {
            prop_assert!(!e.to_string().is_empty());
        }
    }

    /// Chains of `<default>`s, each repeating earlier ones, then uses: the
    /// expansion stays within the caps however they combine.
    #[test]
    fn default_chains_stay_within_the_caps(
        links in proptest::collection::vec(
            (proptest::collection::vec(0..8usize, 1..16), "[a-z0-9.,]{0,12}"), 1..12),
        uses in proptest::collection::vec(0..12usize, 0..40),
        lenient in any::<bool>(),
    ) {
        let mut body = String::from(r#"<default name="p0" value="0.5"/>"#);
        for (k, (refs, literal)) in links.iter().enumerate() {
            let value: String = refs.iter().map(|&r| format!("$p{}", r.min(k))).collect();
            body.push_str(&format!(r#"<default name="p{}" value="{literal}{value}"/>"#, k + 1));
        }
        for u in uses {
            body.push_str(&format!(
                r#"<shape type="sphere"><float name="radius" value="$p{}"/></shape>"#,
                u.min(links.len())
            ));
        }
        check_no_panic(&wrap(&body), lenient);
    }

    #[test]
    fn mutated_cornell_box_never_panics(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), 0..4u8, any::<char>()), 1..8),
        lenient in any::<bool>(),
    ) {
        let original = std::fs::read_to_string(scenes_dir().join("cornell-box.xml")).unwrap();
        check_no_panic(&crate::scene::tests::mutated_text(&original, edits), lenient);
    }
}

/// A strict document is read through, and every unsupported feature is
/// named in one error: the first located, the others listed with their lines.
#[test]
fn strict_documents_name_every_unsupported_feature() {
    let body = r#"<bsdf type="diffuse" id="t"><texture type="gridvolume" name="reflectance">
        </texture></bsdf>
<shape type="rectangle"><ref id="t"/></shape>
<foo/>
<bar/>"#;
    let text = wrap(body);
    let e = load_err(&text);
    let message = e.to_string();
    assert_eq!(syntax_line(&e), line_of(&text, "gridvolume"), "{message}");
    assert!(message.contains("and 2 more"), "{message}");
    for other in ["<foo/>", "<bar/>"] {
        let line = format!("line {}", line_of(&text, other));
        assert!(message.contains(&line), "{other}: {message}");
    }
}

#[test]
fn integrator_depth_becomes_the_scenes_default() {
    let depth = |integrator: &str| ok(integrator).max_depth;
    assert_eq!(depth(""), None);
    assert_eq!(
        depth(r#"<integrator type="path"><integer name="max_depth" value="6"/></integrator>"#),
        Some(6)
    );
    // Unbounded keeps the service's default; `direct` is emission plus direct light.
    assert_eq!(
        depth(r#"<integrator type="path"><integer name="max_depth" value="-1"/></integrator>"#),
        None
    );
    assert_eq!(depth(r#"<integrator type="direct"/>"#), Some(2));
    // A wrapper that only adds outputs takes the depth it nests.
    assert_eq!(
        depth(
            r#"<integrator type="aov"><string name="aovs" value="nn:sh_normal"/>
                 <integrator type="volpath"><integer name="max_depth" value="9"/></integrator>
               </integrator>"#
        ),
        Some(9)
    );
    assert!(
        err(r#"<integrator type="path"><integer name="max_depth" value="0"/></integrator>"#)
            .contains("0 renders nothing")
    );
    assert!(
        err(r#"<integrator type="path"><integer name="max_depth" value="5000"/></integrator>"#)
            .contains("outside")
    );
}

#[test]
fn a_bsdf_no_shape_uses_never_fails_the_scene() {
    let unused = r#"<bsdf type="diffuse" id="volumetric"><texture type="volume" name="reflectance">
          <volume type="gridvolume" name="volume"><string name="filename" value="red.vol"/></volume>
        </texture></bsdf>"#;
    let shape = r#"<shape type="rectangle"><ref id="w"/></shape>"#;
    let (scene, warnings) = load(&wrap(&format!("{unused}\n{shape}"))).expect("loads strictly");
    assert_eq!(scene.material_ids, ["w"]);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let message = &warnings.iter().next().unwrap().message;
    assert!(
        message.contains("\"volumetric\" is used by no shape and left out"),
        "{message}"
    );
    // Used, it is read and refused.
    let used = r#"<shape type="rectangle"><ref id="volumetric"/></shape>"#;
    assert!(err(&format!("{unused}\n{used}")).contains("volume"));
}

/// `b0` diffuse, each `bN` a blend of two references to `bN-1`, and a
/// rectangle made of `b{levels}`: a few kilobytes whose tree doubles at
/// each level.
fn doubling_blends(levels: usize) -> String {
    let mut body = String::from(r#"<bsdf type="diffuse" id="b0"/>"#);
    for n in 1..=levels {
        body += &format!(
            r#"<bsdf type="blendbsdf" id="b{n}"><ref id="b{m}"/><ref id="b{m}"/></bsdf>"#,
            m = n - 1
        );
    }
    body += &format!(r#"<shape type="rectangle"><ref id="b{levels}"/></shape>"#);
    wrap(&body)
}

#[test]
fn referenced_bsdfs_are_shared_and_trees_that_double_are_refused() {
    // Two levels: seven plugins, each referenced BSDF held once.
    let (scene, _) = load(&doubling_blends(2)).unwrap();
    let b2 = scene.material_ids.iter().position(|id| id == "b2").unwrap();
    let Material::Blend(BlendMaterial { bsdfs, .. }) = &scene.materials[b2] else {
        panic!("{:?}", scene.materials[b2])
    };
    assert!(std::sync::Arc::ptr_eq(&bsdfs[0], &bsdfs[1]));
    assert_eq!(scene.materials[b2].nodes_up_to(usize::MAX), 7);
    // Thirty levels in 2 kB: 2³¹ − 1 plugins, refused before any is
    // expanded, naming the material.
    let text = doubling_blends(30);
    assert!(text.len() < 4096);
    let e = load_err(&text).to_string();
    assert!(e.contains("MAX_MATERIAL_NODES"), "{e}");
    assert!(e.contains(r#"<bsdf type="blendbsdf" id="b6">"#), "{e}");
}

/// Thirty dielectrics whose `int_ior` is one 1024² PNG (12 MiB decoded):
/// a strict load refuses them without decoding it (under a budget too small
/// for one decoding), a lenient one decodes it once for all thirty (under a
/// budget too small for two).
#[test]
fn a_texture_where_a_number_is_wanted_is_decoded_once_if_at_all() {
    let dir = Scratch::new("ior-texture");
    image::RgbImage::from_pixel(1024, 1024, image::Rgb([200, 150, 100]))
        .save(dir.0.join("ior.png"))
        .unwrap();
    let shapes: String = (0..30)
        .map(|i| {
            format!(
                r#"<shape type="sphere"><point name="center" x="{i}" y="0" z="0"/>
                   <bsdf type="dielectric"><ref name="int_ior" id="t"/></bsdf></shape>"#
            )
        })
        .collect();
    let text = wrap(&format!(
        r#"<texture type="bitmap" id="t"><string name="filename" value="ior.png"/></texture>{shapes}"#
    ));
    let load = |lenient: bool, max_bytes: u64| {
        let limits = crate::scene::LoadLimits {
            max_bytes,
            ..Default::default()
        };
        super::from_str(&text, "ior.xml", &dir.0, &dir.0, &options(lenient), &limits)
    };
    let e = load(false, 1 << 20).err().unwrap();
    assert!(e.to_string().contains("as a constant"), "{e}");
    let (scene, warnings) = load(true, 48 << 20).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(warnings.total(), 30);
    assert_eq!(scene.files, [std::path::PathBuf::from("ior.png")]);
}

#[test]
fn a_cancelled_load_stops() {
    let cancel = crate::cancel::Cancel::new();
    cancel.cancel();
    let limits = crate::scene::LoadLimits {
        cancel,
        ..Default::default()
    };
    let dir = scenes_dir();
    for file in ["cornell-box.xml", "studio.xml"] {
        let loaded = Scene::load_within(&dir.join(file), &dir, &options(false), &limits);
        assert!(matches!(loaded, Err(SceneError::Cancelled)), "{file}");
    }
    let json = Scene::load_within(&dir.join("mesh.json"), &dir, &options(false), &limits);
    assert!(matches!(json, Err(SceneError::Cancelled)));
}

/// A Mitsuba 0.5 document (camelCase names, `<lookAt>`, a diffuse BSDF's
/// `diffuseReflectance`, `uscale`/`vscale`) is read as Mitsuba 3 upgrades
/// it: the same scene (content digest) as the 3.0 document written by
/// hand, with the upgrades listed among the warnings, in strict mode.
#[test]
fn mitsuba_0_5_documents_are_upgraded_as_mitsuba_3_upgrades_them() {
    let scene = |version: &str, body: &str| {
        let text = format!(
            r#"<scene version="{version}">
  <sensor type="perspective"><float name="fov" value="40"/>
    <transform name="{to_world}"><{lookat} origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="{spp}" value="16"/></sampler>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
  {body}
  <emitter type="point"><point name="position" x="0" y="2" z="2"/><rgb name="intensity" value="1"/></emitter>
</scene>"#,
            to_world = if version == "0.5.0" {
                "toWorld"
            } else {
                "to_world"
            },
            lookat = if version == "0.5.0" {
                "lookAt"
            } else {
                "lookat"
            },
            spp = if version == "0.5.0" {
                "sampleCount"
            } else {
                "sample_count"
            },
        );
        load_in(&text, &scenes_dir(), false).unwrap_or_else(|e| panic!("{version}: {e}"))
    };
    let (old, warnings) = scene(
        "0.5.0",
        r#"<bsdf type="diffuse" id="w"><texture type="checkerboard" name="diffuseReflectance">
             <float name="uscale" value="2"/><float name="vscale" value="3"/></texture></bsdf>
           <bsdf type="dielectric" id="g"><float name="intIOR" value="1.33"/><float name="extIOR" value="1.0"/></bsdf>
           <shape type="sphere"><ref id="g"/></shape>
           <shape type="rectangle"><ref id="w"/><transform name="toWorld"><translate z="-1"/></transform></shape>"#,
    );
    let (new, none) = scene(
        "3.0.0",
        r#"<bsdf type="diffuse" id="w"><texture type="checkerboard" name="reflectance">
             <transform name="to_uv"><scale x="2" y="3"/></transform></texture></bsdf>
           <bsdf type="dielectric" id="g"><float name="int_ior" value="1.33"/><float name="ext_ior" value="1.0"/></bsdf>
           <shape type="sphere"><ref id="g"/></shape>
           <shape type="rectangle"><ref id="w"/><transform name="to_world"><translate z="-1"/></transform></shape>"#,
    );
    assert_eq!(old.digest, new.digest);
    assert_eq!(none.total(), 0, "{none:?}");
    let said: Vec<String> = warnings.iter().map(|w| w.message.clone()).collect();
    for expected in [
        "`toWorld` read as `to_world` (2×)",
        "`intIOR` read as `int_ior` (1×)",
        "<lookAt> read as <lookat> (1×)",
        "a diffuse BSDF's `diffuse_reflectance` read as `reflectance` (1×)",
        "`uoffset`/`voffset`/`uscale`/`vscale` read as a `to_uv` transform (1×)",
    ] {
        assert!(
            said.iter().any(|m| m.ends_with(expected)),
            "{expected}: {said:?}"
        );
    }
}

/// The backticked names of a cell of the plugin table outside parentheses.
fn plugin_names_in(cell: &str) -> Vec<String> {
    let mut names = Vec::new();
    let (mut depth, mut name) = (0, None::<String>);
    for c in cell.chars() {
        match (c, &mut name) {
            ('(', None) => depth += 1,
            (')', None) => depth -= 1,
            ('`', None) if depth == 0 => name = Some(String::new()),
            ('`', Some(n)) => {
                names.push(std::mem::take(n));
                name = None;
            }
            (c, Some(n)) => n.push(c),
            _ => {}
        }
    }
    names
}

/// docs/scene-format.md's "Mitsuba 3's plugins at a glance" against the
/// reader: every plugin of an "exact" cell loads strictly or fails for
/// something other than being unsupported (a probe gives no parameters),
/// and every plugin of a "refused" cell is refused by name.
#[test]
fn the_plugin_table_is_what_the_reader_does() {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/scene-format.md"))
            .unwrap();
    let table = &doc[doc.find("### Mitsuba 3's plugins at a glance").unwrap()..];
    let probe = |kind: &str, name: &str| -> String {
        let body = match kind {
            "BSDFs" => format!(
                r#"<bsdf type="{name}" id="p"/><shape type="rectangle"><ref id="p"/></shape>"#
            ),
            "textures" => format!(
                r#"<shape type="rectangle"><bsdf type="diffuse"><texture type="{name}" name="reflectance"/></bsdf></shape>"#
            ),
            "emitters" if name == "area" => {
                r#"<shape type="rectangle"><emitter type="area"/></shape>"#.to_string()
            }
            "emitters" => format!(r#"<emitter type="{name}"/>"#),
            "shapes" if name == "instance" => r#"<shape type="shapegroup" id="g">
                <shape type="disk"/></shape><shape type="instance"><ref id="g"/></shape>"#
                .to_string(),
            "shapes" => format!(r#"<shape type="{name}"/>"#),
            "sensors" if name.ends_with("meter") => {
                return match load(&format!(
                    r#"<scene version="3.0.0"><shape type="disk"><sensor type="{name}"/></shape></scene>"#
                )) {
                    Ok(_) => String::new(),
                    Err(e) => e.to_string(),
                };
            }
            "sensors" => {
                return match load(&format!(
                    r#"<scene version="3.0.0"><sensor type="{name}"/></scene>"#
                )) {
                    Ok(_) => String::new(),
                    Err(e) => e.to_string(),
                };
            }
            _ => unreachable!(),
        };
        match load(&wrap(&body)) {
            Ok(_) => String::new(),
            Err(e) => e.to_string(),
        }
    };
    let mut checked = 0;
    for row in table.lines().filter(|l| l.starts_with("| ")) {
        let cells: Vec<&str> = row.split(" | ").collect();
        let kind = cells[0].trim_start_matches("| ");
        if !["BSDFs", "textures", "emitters", "shapes", "sensors"].contains(&kind) {
            continue;
        }
        for name in plugin_names_in(cells[1]) {
            let e = probe(kind, &name);
            assert!(!e.contains("not supported"), "{kind} {name} is exact: {e}");
            checked += 1;
        }
        for name in plugin_names_in(cells[3]) {
            let e = probe(kind, &name);
            assert!(
                e.contains("not supported") && e.contains(&name),
                "{kind} {name} is refused: {e:?}"
            );
            checked += 1;
        }
    }
    assert!(checked > 40, "{checked} names read from the table");
}

#[test]
fn a_bump_maps_height_texture_may_have_any_name_but_only_one() {
    use crate::scene::material::Material;
    let checker = |name: &str| {
        format!(
            r#"<texture type="checkerboard" name="{name}"><rgb name="color0" value="0.2"/></texture>"#
        )
    };
    let scene = ok(&format!(
        r#"<shape type="rectangle"><bsdf type="bumpmap">{}<float name="scale" value="0.5"/>
           <bsdf type="roughplastic"/></bsdf></shape>"#,
        checker("arbitrary")
    ));
    assert!(
        scene
            .materials
            .iter()
            .any(|m| matches!(m, Material::BumpMap(b) if b.scale == 0.5)),
        "{:?}",
        scene.materials
    );
    let e = err(&format!(
        r#"<shape type="rectangle"><bsdf type="bumpmap">{}{}<bsdf type="diffuse"/></bsdf></shape>"#,
        checker("one"),
        checker("two")
    ));
    assert!(e.contains("no supported property \"two\""), "{e}");
    let e = err(
        r#"<shape type="rectangle"><bsdf type="normalmap"><bsdf type="diffuse"/></bsdf></shape>"#,
    );
    assert!(e.contains("normalmap"), "{e}");
}
