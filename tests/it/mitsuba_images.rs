//! Mitsuba 3 scene files path traced by us and by Mitsuba 3.9.1, compared
//! image to image: the mean ratio within 1 %, the relative RMSE over
//! 8×8-pixel blocks within 2 % (the noise of both images included), and
//! per pixel within 1.25× what our image's own variance explains. The
//! references are Mitsuba's renders at 16,384 spp with each file's own
//! reconstruction filter (box, Gaussian or tent, which our film reads as
//! Mitsuba does), made by the scripts named beside each test.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use bmc_irradiance::image::{Image, read_exr, relative_rmse};
use bmc_irradiance::integrator::PathIntegrator;
use bmc_irradiance::render::ImageSettings;
use bmc_irradiance::{MitsubaOptions, PathDepth, Scene, Transport};

/// Side of the square blocks images are compared in.
const BLOCK: u32 = 8;

/// The mean of each `BLOCK × BLOCK` block of `image`.
fn blocks(image: &Image) -> Image {
    let (w, h) = (image.width() / BLOCK, image.height() / BLOCK);
    let mut rgb = vec![[0.0f32; 3]; (w * h) as usize];
    for y in 0..h * BLOCK {
        for x in 0..w * BLOCK {
            let p = image.pixel(x, y).unwrap();
            let b = &mut rgb[((y / BLOCK) * w + x / BLOCK) as usize];
            for c in 0..3 {
                b[c] += p[c] / (BLOCK * BLOCK) as f32;
            }
        }
    }
    Image::from_parts(w, h, rgb, None).unwrap()
}

/// Path depth for a file whose `<integrator>` sets none or Mitsuba's `-1`
/// (no limit): 64 segments leave no visible truncation in these scenes.
const UNLIMITED_DEPTH: u32 = 64;

/// Loads `dir/file` strictly with `parameters`, path traces it at 1,024
/// spp and the depth of its own `<integrator>`, and compares it with
/// Mitsuba's `dir/reference`.
fn assert_agrees_with_mitsuba(dir: &str, file: &str, parameters: &[(&str, &str)], reference: &str) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
    let options = MitsubaOptions {
        parameters: parameters
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect::<BTreeMap<_, _>>(),
        ..MitsubaOptions::default()
    };
    let (scene, warnings) = Scene::load_mitsuba_xml(&dir.join(file), &dir, &options)
        .unwrap_or_else(|e| panic!("{file} loads strictly: {e}"));
    // Only filters with negative lobes may be approximated (by the pixel's
    // box); a Mitsuba 0.x file also lists what was upgraded.
    assert!(
        warnings
            .iter()
            .all(|w| w.message.contains("reconstruction filter")
                || w.message.starts_with("Mitsuba 0.x upgrade")),
        "{warnings:?}"
    );
    let max_depth = PathDepth::new(scene.max_depth.unwrap_or(UNLIMITED_DEPTH)).unwrap();
    let transport = Transport::new(Arc::new(scene));
    let settings = ImageSettings {
        samples_per_pixel: 1024,
        max_depth,
        seed: 1,
    };
    let ours = PathIntegrator::new(&transport)
        .render_image(&settings, 16, &|_| {})
        .unwrap()
        .image;
    let theirs = read_exr(&dir.join(reference)).unwrap();
    let whole = relative_rmse(&ours, &theirs, None).unwrap();
    assert!((whole.mean_ratio - 1.0).abs() < 0.01, "{file}: {whole:?}");
    let by_block = relative_rmse(&blocks(&ours), &blocks(&theirs), None).unwrap();
    assert!(by_block.overall < 0.02, "{file}: {by_block:?}");
    // Pixel by pixel, the images differ by their noise alone.
    let noise = whole
        .expected_from_variance
        .expect("our image has its variance");
    assert!(whole.overall < 1.25 * noise, "{file}: {whole:?}");
}

/// The tutorials' Cornell box with a glass sphere (`dielectric`, BK7 in
/// air by default) and a mirror sphere (`conductor`, `none`), at its own
/// `max_depth` 6, tent filter and 64² (`tests/data/mitsuba-tutorials/`,
/// reference by `docs/validation/mitsuba_tutorial_cbox.py`). Measured with
/// `render --param res=64 --spp 1024` and `compare`: 7.2 % per pixel
/// against 13.5 % expected from the noise, mean ratio 0.9995; the same
/// file read with a box filter reads 46.8 %, the light's edge unblurred.
#[test]
fn cbox_with_glass_and_mirror_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba-tutorials",
        "cbox.xml",
        &[("res", "64")],
        "cbox_mitsuba_64.exr",
    );
}

/// Point, spot and directional lights on rough gold (GGX), rough plastic
/// (Beckmann) and a two-sided disk seen from both sides
/// (`tests/data/mitsuba/lights.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`). Measured: mean ratio 1.0014,
/// 0.81 % over blocks (6.8 % per pixel).
#[test]
fn delta_lights_and_rough_materials_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "lights.xml",
        &[],
        "lights_mitsuba.exr",
    );
}

/// Colours given as spectra, read as Mitsuba 3's RGB variants read them: a
/// one-valued spectrum on an area light (the equal-energy white), sampled
/// spectra on a point light, on reflectances and on a conductor's `eta` and
/// `k`, and a reflectance from a `.spd` file (`tests/data/mitsuba/spectra.xml`,
/// reference by `docs/validation/mitsuba_scene_images.py`). Measured: mean
/// ratio 0.9995, 0.38 % over blocks (2.5 % per pixel). Read as grey, as
/// before, the area light's red was 1/1.2048 of Mitsuba's.
#[test]
fn spectra_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "spectra.xml",
        &[],
        "spectra_mitsuba.exr",
    );
}

/// Analytic cylinders: a textured one along a slanted axis under a rotated,
/// scaled `to_world` (its frame and texture coordinates), an open one seen
/// inside, and an emitting one sampled by area
/// (`tests/data/mitsuba/cylinders.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`). Measured: mean ratio 1.0009,
/// 0.32 % over blocks (2.8 % per pixel); with u mirrored, 2.2 % over blocks.
#[test]
fn cylinders_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "cylinders.xml",
        &[],
        "cylinders_mitsuba.exr",
    );
}

/// Bump and normal maps (`bumpmap`, `normalmap`) over rough plastic,
/// diffuse and rough copper: a bump-mapped floor and sphere (analytic, u
/// round the azimuth), a normal-mapped sphere, a normal-mapped OBJ quad
/// with mirrored texture coordinates, and a two-sided bump-mapped disk seen
/// from behind (`tests/data/mitsuba/shading_normals.xml`, maps and
/// reference by `docs/validation/mitsuba_scene_images.py`). Measured:
/// 1.53 % per pixel against 1.70 % from the noise, mean ratio 0.99997;
/// without the maps' shadowing term 3.5 %, with the bumps flat 5.8 %.
#[test]
fn bump_and_normal_maps_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "shading_normals.xml",
        &[],
        "shading_normals_mitsuba.exr",
    );
}

/// The principled BSDF (`principled`): Mitsuba's defaults, a tinted
/// anisotropic half-metal, clearcoat, sheen and flatness over textured base
/// colour and roughness, and transmission on a sphere and a thin slab
/// (`tests/data/mitsuba/principled.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`). Measured: 3.04 % per pixel
/// against 3.62 % from the noise, mean ratio 0.9993; without the clearcoat,
/// sheen and anisotropy 7.9 %.
#[test]
fn the_principled_bsdf_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "principled.xml",
        &[],
        "principled_mitsuba.exr",
    );
}

/// The thin principled BSDF (`principledthin`): sheets lit from behind
/// passing light diffusely, specularly (rough, anisotropic) or both, with
/// sheen, flatness, a tinted specular and a bitmap base colour, one seen
/// from its back (`tests/data/mitsuba/principled_thin.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`). Measured: 2.01 % per pixel
/// against 2.22 % from the noise, mean ratio 1.00004; without the sheen and
/// anisotropy 3.4 %.
#[test]
fn the_thin_principled_bsdf_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "principled_thin.xml",
        &[],
        "principled_thin_mitsuba.exr",
    );
}

/// An orthographic sensor sized by its `to_world`'s scale, wider than tall,
/// looking obliquely at spheres, a textured cylinder and a floor
/// (`tests/data/mitsuba/orthographic.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`).
#[test]
fn orthographic_sensor_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "orthographic.xml",
        &[],
        "orthographic_mitsuba.exr",
    );
}

/// A Mitsuba 0.6 file in the template that published point-cloud figures
/// are rendered with (camelCase properties, `ldsampler`, clip planes, a
/// film `banner`, `maxDepth` −1), filled with 200 points of our own
/// (`tests/data/mitsuba/point_cloud_0_6.xml`, file and reference by
/// `docs/validation/mitsuba_scene_images.py`): it loads strictly, upgraded
/// as Mitsuba 3 upgrades it, and renders as Mitsuba 3 renders it.
/// Measured: mean ratio 1.00005, 0.07 % over blocks (0.63 % per pixel).
#[test]
fn a_mitsuba_0_6_point_cloud_scene_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "point_cloud_0_6.xml",
        &[],
        "point_cloud_0_6_mitsuba.exr",
    );
}

/// Bitmaps (8-bit sRGB PNG, linear EXR; nearest and bilinear; repeat,
/// mirror and clamp; `to_uv`) and checkerboards on rectangles, a rotated
/// cube, a rotated sphere, a disk, an OBJ quad and a PLY quad
/// (`tests/data/mitsuba/textures.xml`, reference and texture images by
/// `docs/validation/mitsuba_scene_images.py`): every shape's texture
/// coordinates as Mitsuba 3 defines them.
#[test]
fn textures_and_texture_coordinates_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "textures.xml",
        &[],
        "textures_mitsuba.exr",
    );
}

/// Area lights with textured radiance: checkerboards on a rectangle and a
/// sphere, the grid image on a disk, seen directly and lighting diffuse
/// surfaces; the lights have no BSDF, so they are black to light, as in
/// Mitsuba (`tests/data/mitsuba/textured_lights.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`).
#[test]
fn textured_area_lights_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "textured_lights.xml",
        &[],
        "textured_lights_mitsuba.exr",
    );
}

/// Anisotropic rough metal on a PLY quad whose `u` runs along its `y`, a
/// rectangle turned about its normal, a rotated sphere and a disk: each
/// lobe turns with its shape's ∂p/∂u (`tests/data/mitsuba/anisotropy.xml`,
/// reference by `docs/validation/mitsuba_scene_images.py`).
#[test]
fn anisotropic_lobes_follow_each_shapes_u_direction_as_in_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "anisotropy.xml",
        &[],
        "anisotropy_mitsuba.exr",
    );
}

/// Roughness maps: a checkerboard `alpha_u` on rough silver, a raw bitmap
/// `alpha` on rough copper and on a rough dielectric
/// (`tests/data/mitsuba/rough_maps.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`).
#[test]
fn roughness_maps_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "rough_maps.xml",
        &[],
        "rough_maps_mitsuba.exr",
    );
}

/// `blendbsdf` (a checkerboard weight between rough gold and diffuse),
/// `mask` (a bitmap opacity over a two-sided diffuse, and a constant one),
/// `thindielectric`, `roughdielectric` and `plastic`
/// (`tests/data/mitsuba/materials.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`).
#[test]
fn blend_mask_and_other_materials_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "materials.xml",
        &[],
        "materials_mitsuba.exr",
    );
}

/// An `envmap` from a Radiance HDR file, rotated and scaled, seen directly
/// (where its bilinear lookup shows on a 32 × 16 map) and lighting a
/// diffuse and a rough metal sphere (`tests/data/mitsuba/envmap.xml`,
/// reference and map by `docs/validation/mitsuba_scene_images.py`).
#[test]
fn hdr_environment_map_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "envmap.xml",
        &[],
        "envmap_mitsuba.exr",
    );
}

/// `hide_emitters`: camera rays pass through an area light and see black
/// where the environment would be, while both still light the scene
/// (`tests/data/mitsuba/hide_emitters.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`, with the file's Gaussian
/// filter). Measured as the test does: 1.68 % per pixel against 2.14 %
/// expected from the noise; read with a box filter, 6.79 %.
#[test]
fn hidden_emitters_agree_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "hide_emitters.xml",
        &[],
        "hide_emitters_mitsuba.exr",
    );
}

/// A `thinlens` camera: the near and far spheres and the floor's pattern
/// blur as in Mitsuba (`tests/data/mitsuba/thinlens.xml`, reference by
/// `docs/validation/mitsuba_scene_images.py`).
#[test]
fn thin_lens_depth_of_field_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "tests/data/mitsuba",
        "thinlens.xml",
        &[],
        "thinlens_mitsuba.exr",
    );
}

/// The bundled studio scene (`scenes/studio.xml`: glass, GGX gold on a
/// mesh given smooth normals, a textured rough-plastic floor, plastic, a
/// two-sided panel, point and spot lights, an HDR sky) at 80×60 (reference
/// by `docs/validation/mitsuba_scene_images.py studio`).
#[test]
fn the_bundled_studio_scene_agrees_with_mitsuba() {
    assert_agrees_with_mitsuba(
        "scenes",
        "studio.xml",
        &[("resx", "80"), ("resy", "60")],
        "../tests/data/mitsuba/studio_mitsuba.exr",
    );
}
