use std::path::Path;

use glam::{DAffine2, DVec2};
use serde_json::json;

use super::bitmap::{BitmapTexture, Filter, Wrap};
use super::checkerboard::CheckerboardTexture;
use super::*;
use crate::scene::bitmap::{self, Bitmaps, read_bitmap};
use crate::scene::budget::{Budget, LoadLimits};
use crate::scene::files::Files;

/// A load budget of the library's own bounds.
fn unlimited() -> Budget {
    Budget::new(&LoadLimits::default())
}

/// A 2 × 2 bitmap: red, green on the top row; blue, white below.
fn quad(filter: Filter, wrap: Wrap) -> BitmapTexture {
    let texels = vec![
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ];
    BitmapTexture {
        bitmap: Arc::new(Bitmap::new(2, 2, texels).unwrap()),
        filter,
        wrap,
        to_uv: DAffine2::IDENTITY,
    }
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
}

#[test]
fn bilinear_lookup_is_exact_at_texel_centres_and_blends_between() {
    let t = quad(Filter::Bilinear, Wrap::Repeat);
    // v = 0 is the top row.
    assert!(close(t.eval(DVec2::new(0.25, 0.25)), [1.0, 0.0, 0.0]));
    assert!(close(t.eval(DVec2::new(0.75, 0.25)), [0.0, 1.0, 0.0]));
    assert!(close(t.eval(DVec2::new(0.25, 0.75)), [0.0, 0.0, 1.0]));
    // Midway between red and green; the centre blends all four.
    assert!(close(t.eval(DVec2::new(0.5, 0.25)), [0.5, 0.5, 0.0]));
    assert!(close(t.eval(DVec2::new(0.5, 0.5)), [0.5, 0.5, 0.5]));
    // Periodic: one period over gives the same colour.
    assert!(close(
        t.eval(DVec2::new(1.3, -0.8)),
        t.eval(DVec2::new(0.3, 0.2))
    ));
}

#[test]
fn wrap_modes_differ_only_beyond_the_texel_centres() {
    // u = 0 lies half a texel left of the first centre.
    let at_edge = |wrap| quad(Filter::Bilinear, wrap).eval(DVec2::new(0.0, 0.25));
    // Repeat blends with the last column, clamp and mirror with the first.
    assert!(close(at_edge(Wrap::Repeat), [0.5, 0.5, 0.0]));
    assert!(close(at_edge(Wrap::Clamp), [1.0, 0.0, 0.0]));
    assert!(close(at_edge(Wrap::Mirror), [1.0, 0.0, 0.0]));
    // Beyond the image: clamp keeps the edge; mirror reflects (texel −1 is
    // texel 0, −2 is texel 1).
    let far = |wrap| quad(Filter::Nearest, wrap).eval(DVec2::new(-0.75, 0.25));
    assert!(close(far(Wrap::Clamp), [1.0, 0.0, 0.0]));
    assert!(close(far(Wrap::Mirror), [0.0, 1.0, 0.0]));
    assert!(close(far(Wrap::Repeat), [1.0, 0.0, 0.0]));
}

#[test]
fn nearest_lookup_picks_the_texel_under_the_point() {
    let t = quad(Filter::Nearest, Wrap::Repeat);
    assert!(close(t.eval(DVec2::new(0.49, 0.51)), [0.0, 0.0, 1.0]));
    assert!(close(t.eval(DVec2::new(0.51, 0.49)), [0.0, 1.0, 0.0]));
}

#[test]
fn checkerboard_alternates_per_half_period_and_follows_to_uv() {
    let board = CheckerboardTexture {
        color0: [0.4; 3],
        color1: [0.2; 3],
        to_uv: DAffine2::IDENTITY,
    };
    assert_eq!(board.eval(DVec2::new(0.25, 0.25)), [0.4; 3]);
    assert_eq!(board.eval(DVec2::new(0.75, 0.25)), [0.2; 3]);
    assert_eq!(board.eval(DVec2::new(0.75, 0.75)), [0.4; 3]);
    assert_eq!(board.eval(DVec2::new(-0.25, 0.25)), [0.2; 3]);
    let scaled = CheckerboardTexture {
        to_uv: DAffine2::from_scale(DVec2::splat(2.0)),
        ..board.clone()
    };
    assert_eq!(scaled.eval(DVec2::new(0.375, 0.125)), [0.2; 3]);
    assert_eq!(board.mean(), [0.30000000000000004; 3]);
}

/// A scratch directory, removed on drop.
struct Scratch(std::path::PathBuf);

impl Scratch {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("bmc-texture-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir.canonicalize().unwrap())
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn read(path: &Path, raw: bool) -> Bitmap {
    read_bitmap(path, raw, "reflectance", &unlimited()).unwrap()
}

#[test]
fn every_format_decodes_to_linear_rgb() {
    let dir = Scratch::new("formats");
    let srgb_188 = bitmap::srgb_to_linear(188.0 / 255.0);
    // 8-bit PNG: sRGB-decoded unless raw.
    let png8 = dir.0.join("a.png");
    image::RgbImage::from_raw(2, 1, vec![255, 0, 188, 0, 0, 0])
        .unwrap()
        .save(&png8)
        .unwrap();
    let b = read(&png8, false);
    assert_eq!((b.width(), b.height()), (2, 1));
    assert!((b.texel(0, 0)[2] - srgb_188).abs() < 1e-6);
    assert!((read(&png8, true).texel(0, 0)[2] - 188.0 / 255.0).abs() < 1e-6);
    // 16-bit PNG.
    let png16 = dir.0.join("b.png");
    image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(1, 1, vec![65535u16, 32768, 0])
        .unwrap()
        .save(&png16)
        .unwrap();
    let t = read(&png16, false).texel(0, 0);
    assert!(
        (t[0] - 1.0).abs() < 1e-6
            && (t[1] - bitmap::srgb_to_linear(32768.0 / 65535.0)).abs() < 1e-6
    );
    // JPEG (lossy: a flat colour survives within a few codes).
    let jpg = dir.0.join("c.jpg");
    image::RgbImage::from_pixel(16, 16, image::Rgb([188, 188, 188]))
        .save(&jpg)
        .unwrap();
    let t = read(&jpg, false).texel(7, 7);
    assert!((t[1] - srgb_188).abs() < 0.01, "{t:?}");
    // Radiance HDR and EXR: linear, values above 1 kept.
    let hdr = dir.0.join("d.hdr");
    image::Rgb32FImage::from_raw(1, 1, vec![2.5, 0.5, 0.25])
        .unwrap()
        .save(&hdr)
        .unwrap();
    let t = read(&hdr, false).texel(0, 0);
    assert!(
        (t[0] - 2.5).abs() < 0.02 && (t[2] - 0.25).abs() < 0.01,
        "{t:?}"
    );
    let exr = dir.0.join("e.exr");
    crate::scene::write_exr_half(&exr, 1, 1, &[[3.0, 0.5, 0.25]]).unwrap();
    let t = read(&exr, false).texel(0, 0);
    assert!((t[0] - 3.0).abs() < 1e-3, "{t:?}");
    // Not an image.
    let txt = dir.0.join("f.png");
    std::fs::write(&txt, "hello").unwrap();
    let e = read_bitmap(&txt, false, "reflectance", &unlimited()).unwrap_err();
    assert_eq!(e.field(), Some("reflectance"));
}

#[test]
fn texture_documents_are_validated_naming_the_field() {
    let dir = Scratch::new("docs");
    image::RgbImage::from_pixel(4, 2, image::Rgb([255, 255, 255]))
        .save(dir.0.join("white.png"))
        .unwrap();
    crate::scene::write_exr_half(&dir.0.join("bright.exr"), 1, 1, &[[2.0, 0.5, 0.5]]).unwrap();
    let files = Files::new(&dir.0, &dir.0).unwrap();
    let budget = unlimited();
    let bitmaps = Bitmaps::new(&files, &budget);
    let parse = |doc: serde_json::Value| {
        let serde_json::Value::Object(map) = json!({ "reflectance": doc }) else {
            unreachable!()
        };
        let mut params = Params::new("materials[2]", map).with_bitmaps(&bitmaps);
        albedo(&mut params, "reflectance", [0.5; 3])
    };
    let field = |doc| parse(doc).unwrap_err().field().unwrap().to_string();
    let t = parse(
        json!({"type": "bitmap", "filename": "white.png", "wrap_mode": "clamp",
        "to_uv": {"scale": [2, 2, 1]}}),
    )
    .unwrap();
    let Texture::Bitmap(b) = &t else {
        panic!("{t:?}")
    };
    assert_eq!(
        (b.wrap, b.filter, b.bitmap.width()),
        (Wrap::Clamp, Filter::Bilinear, 4)
    );
    assert_eq!(b.to_uv.matrix2.x_axis.x, 2.0);
    assert_eq!(
        field(json!({"type": "marble"})),
        "materials[2].reflectance.type"
    );
    assert_eq!(field(json!({"type": "bitmap"})), "materials[2].reflectance");
    assert_eq!(
        field(json!({"type": "bitmap", "filename": "white.png", "wrap_mode": "tile"})),
        "materials[2].reflectance.wrap_mode"
    );
    assert_eq!(
        field(json!({"type": "bitmap", "filename": "missing.png"})),
        "materials[2].reflectance.filename"
    );
    assert_eq!(
        field(json!({"type": "bitmap", "filename": "../outside.png"})),
        "materials[2].reflectance.filename"
    );
    assert_eq!(
        field(json!({"type": "checkerboard", "colour0": 1})),
        "materials[2].reflectance.colour0"
    );
    assert_eq!(
        field(json!({"type": "checkerboard", "to_uv": {"scale": [1, 0, 1]}})),
        "materials[2].reflectance.to_uv"
    );
    // A texture above 1 is not an albedo.
    assert_eq!(
        field(json!({"type": "bitmap", "filename": "bright.exr"})),
        "materials[2].reflectance"
    );
}

#[test]
fn a_scenes_images_are_capped_in_all() {
    let dir = Scratch::new("cap");
    for name in ["a.png", "b.png"] {
        image::RgbImage::from_pixel(4, 4, image::Rgb([9, 9, 9]))
            .save(dir.0.join(name))
            .unwrap();
    }
    let files = Files::new(&dir.0, &dir.0).unwrap();
    let budget = unlimited();
    let bitmaps = Bitmaps::with_limit(&files, &budget, 20);
    let a = bitmaps
        .load("a.png", false, "materials[0].reflectance.filename")
        .unwrap();
    // The same file again is shared, not counted twice.
    assert!(Arc::ptr_eq(&a, &bitmaps.load("a.png", false, "x").unwrap()));
    let e = bitmaps
        .load("b.png", false, "materials[1].reflectance.filename")
        .unwrap_err();
    assert_eq!(e.field(), Some("materials[1].reflectance.filename"));
    assert!(
        e.to_string().contains("32 texels in all, more than 20"),
        "{e}"
    );
}

#[test]
fn a_bilinear_bitmaps_gradient_is_the_derivative_of_its_lookup() {
    // Central differences of `eval_scalar` away from texel centres (where
    // the bilinear blend has kinks), through a rotating, scaling to_uv.
    let mut t = quad(Filter::Bilinear, Wrap::Repeat);
    t.to_uv =
        DAffine2::from_scale_angle_translation(DVec2::new(1.5, 0.7), 0.4, DVec2::new(0.1, 0.3));
    let h = 1e-6;
    for uv in [
        DVec2::new(0.1, 0.2),
        DVec2::new(0.43, 0.91),
        DVec2::new(0.77, 0.35),
    ] {
        let g = t.gradient_scalar(uv);
        let d = |e: DVec2| (t.eval_scalar(uv + e) - t.eval_scalar(uv - e)) / (2.0 * h);
        let want = DVec2::new(d(DVec2::new(h, 0.0)), d(DVec2::new(0.0, h)));
        assert!(
            (g - want).length() < 1e-5 * (1.0 + want.length()),
            "{uv}: {g} vs {want}"
        );
        assert!(want.length() > 0.1, "a texture that varies at {uv}");
    }
    // Nearest-texel lookups and constants are flat almost everywhere.
    let nearest = quad(Filter::Nearest, Wrap::Repeat);
    assert_eq!(nearest.gradient_scalar(DVec2::new(0.3, 0.6)), DVec2::ZERO);
    assert_eq!(
        Texture::Constant([0.2; 3]).gradient_scalar(DVec2::new(0.3, 0.6)),
        DVec2::ZERO
    );
}
