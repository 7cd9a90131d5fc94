//! Scene-level tests: the bundled scenes, intersection and normal
//! orientation of every shape kind, area sampling, robust secondary rays,
//! and loader errors that name the field or file.

use std::path::{Path, PathBuf};

use glam::DVec3;
use proptest::prelude::prop;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::*;

/// `original` with character edits applied in order: each `(at, op, c)`
/// removes (`op` 0), inserts `c` (1), replaces by `c` (2) or duplicates the
/// 64 characters at `at` (3, which repeats keys, values, entries, elements
/// and attributes). The parsers' fuzz tests mutate the bundled scenes with it.
pub(crate) fn mutated_text(original: &str, edits: Vec<(prop::sample::Index, u8, char)>) -> String {
    let mut chars: Vec<char> = original.chars().collect();
    for (at, op, c) in edits {
        let i = at.index(chars.len().max(1)).min(chars.len());
        match op {
            0 if i < chars.len() => {
                chars.remove(i);
            }
            1 => chars.insert(i, c),
            2 if i < chars.len() => chars[i] = c,
            _ => {
                let end = (i + 64).min(chars.len());
                let copy: Vec<char> = chars[i..end].to_vec();
                chars.splice(i..i, copy);
            }
        }
    }
    chars.into_iter().collect()
}

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

fn bundled(name: &str) -> Scene {
    let dir = scenes_dir();
    Scene::load(&dir.join(name), &dir).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("bmc-scene-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Wraps shape and extra top-level JSON into a scene with one material.
fn scene_json(shapes: &str, extra: &str) -> String {
    format!(
        r#"{{ "materials": [{{"id": "m", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}}],
             "shapes": [{shapes}],
             "camera": {{"fov": 40, "width": 8, "height": 8,
                         "origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}}
             {extra} }}"#
    )
}

fn from_str(text: &str, root: &Path) -> Result<Scene, SceneError> {
    Scene::from_json_str(text, root, root)
}

fn ray(origin: DVec3, dir: DVec3) -> Ray {
    Ray {
        origin,
        dir: dir.normalize(),
        t_max: f64::INFINITY,
    }
}

#[test]
fn cornell_box_matches_the_mitsuba_reference() {
    let scene = bundled("cornell-box.json");
    assert_eq!(scene.triangle_count(), 36);
    assert_eq!(scene.material_ids, ["white", "green", "red"]);
    // Floor: spans x, z ∈ [-1, 1] at y = -1 and faces up.
    for (x, z) in [(0.99, 0.99), (-0.99, -0.99), (0.99, -0.99), (-0.2, 0.99)] {
        let hit = scene
            .intersect(&ray(DVec3::new(x, -0.5, z), -DVec3::Y))
            .unwrap();
        assert!((hit.position.y + 1.0).abs() < 1e-7, "{hit:?}");
        assert!((hit.normal - DVec3::Y).length() < 1e-6);
        assert_eq!(scene.material_ids[hit.material], "white");
    }
    assert!(
        scene
            .intersect(&ray(DVec3::new(1.01, -0.5, 0.0), -DVec3::Y))
            .is_none()
    );
    // Red wall at x = -1 faces +x, green at x = +1 faces -x.
    let red = scene
        .intersect(&ray(DVec3::new(0.0, 0.5, 0.0), -DVec3::X))
        .unwrap();
    assert_eq!(scene.material_ids[red.material], "red");
    assert!((red.normal - DVec3::X).length() < 1e-6 && (red.position.x + 1.0).abs() < 1e-7);
    let green = scene
        .intersect(&ray(DVec3::new(0.0, 0.5, 0.0), DVec3::X))
        .unwrap();
    assert_eq!(scene.material_ids[green.material], "green");
    assert!((green.normal + DVec3::X).length() < 1e-6);
    // The light: centre (0, 0.99, 0.01), 0.46 × 0.38, facing -y, white BSDF.
    assert_eq!(scene.emitters.len(), 1);
    let Emitter::Area(emitter::AreaLight { shape, radiance }) = scene.emitters[0].clone() else {
        panic!("{:?}", scene.emitters[0])
    };
    assert_eq!(
        radiance,
        texture::Texture::Constant([18.387, 13.9873, 6.75357])
    );
    assert!((scene.shape_area(shape) - 0.46 * 0.38).abs() < 1e-6);
    let hit = scene
        .intersect(&ray(DVec3::new(0.0, 0.5, 0.01), DVec3::Y))
        .unwrap();
    assert_eq!(hit.emitter, Some(0));
    assert_eq!(hit.shape, shape);
    assert_eq!(scene.material_ids[hit.material], "white");
    assert!((hit.position - DVec3::new(0.0, 0.99, 0.01)).length() < 1e-7);
    assert!((hit.normal + DVec3::Y).length() < 1e-6);
    // Boxes: the small box top at y = -0.4, the large box top at y = 0.21.
    let top = scene
        .intersect(&ray(DVec3::new(0.335, 0.0, 0.38), -DVec3::Y))
        .unwrap();
    assert!((top.position.y + 0.4).abs() < 1e-6 && (top.normal - DVec3::Y).length() < 1e-6);
    let top = scene
        .intersect(&ray(DVec3::new(-0.33, 0.5, -0.28), -DVec3::Y))
        .unwrap();
    assert!((top.position.y - 0.21).abs() < 1e-6);
    let (lo, hi) = scene.bounds();
    // The large box reaches 1 cm below the floor, as in Mitsuba.
    assert!((lo - DVec3::new(-1.0, -1.01, -1.0)).abs().max_element() < 1e-6);
    assert!((hi - DVec3::splat(1.0)).abs().max_element() < 1e-6);
    // Camera: Mitsuba's, at z = 3.9 looking down -z, 256².
    assert_eq!(scene.camera.resolution(), (256, 256));
    let centre = scene.camera.generate_ray(128.0, 128.0);
    assert!((centre.origin - DVec3::new(0.0, 0.0, 3.9)).length() < 1e-6);
    assert!((centre.dir + DVec3::Z).length() < 1e-6);
    let left = scene
        .intersect(&scene.camera.generate_ray(30.0, 128.0))
        .unwrap();
    assert_eq!(scene.material_ids[left.material], "red");
}

#[test]
fn every_shape_kind_hits_with_its_authored_normal() {
    let dir = TempDir::new("kinds");
    let shapes = r#"
        {"type": "rectangle", "material": "m", "to_world": [{"translate": [0, 0, -3]}]},
        {"type": "cube", "material": "m", "to_world": {"translate": [4, 0, 0]}},
        {"type": "sphere", "material": "m", "center": [0, 5, 0], "radius": 0.5,
         "to_world": {"scale": [2, 2, 2]}},
        {"type": "disk", "material": "m", "flip_normals": true,
         "to_world": [{"rotate": {"axis": [1, 0, 0], "angle": 90}}, {"translate": [0, -4, 0]}]},
        {"type": "triangles", "material": "m", "positions": [[-1, 0, 8], [1, 0, 8], [0, 1, 8]],
         "indices": [[0, 1, 2]]}"#;
    let scene = from_str(&scene_json(shapes, ""), &dir.0).unwrap();
    assert_eq!(scene.shape_count(), 5);
    assert_eq!(scene.triangle_count(), 2 + 12 + 1);
    let o = DVec3::ZERO;
    let cases = [
        (-DVec3::Z, 0, 3.0, DVec3::Z),                 // rectangle faces +z
        (DVec3::X, 1, 3.0, -DVec3::X),                 // cube outer face at x = 3
        (DVec3::Y, 2, 9.0, -DVec3::Y),                 // sphere centre (0,10,0), r = 1
        (-DVec3::Y, 3, 4.0, DVec3::Y),                 // disk: +z → -y, flipped → +y
        (DVec3::new(0.0, 0.3, 8.0), 4, 0.0, DVec3::Z), // triangle in z = 8, seen from behind
    ];
    for (d, shape, t, normal) in cases {
        let hit = scene.intersect(&ray(o, d)).unwrap();
        assert_eq!(hit.shape, shape, "{d}");
        if t > 0.0 {
            assert!((hit.t - t).abs() < 1e-12, "{hit:?}");
        }
        assert!((hit.normal - normal).length() < 1e-12, "{hit:?}");
        assert!(scene.occluded(&Ray {
            t_max: hit.t * 1.001,
            ..ray(o, d)
        }));
        assert!(!scene.occluded(&Ray {
            t_max: hit.t * 0.999,
            ..ray(o, d)
        }));
    }
    // From inside the cube its faces point away from the ray.
    let inside = scene
        .intersect(&ray(DVec3::new(4.0, 0.0, 0.0), DVec3::Y))
        .unwrap();
    assert!((inside.normal - DVec3::Y).length() < 1e-12 && (inside.t - 1.0).abs() < 1e-12);
}

/// Texture coordinates as `docs/scene-format.md` states them (checked
/// against Mitsuba 3 image to image in `tests/it/mitsuba_images.rs`).
#[test]
fn hits_report_each_shape_kinds_texture_coordinates() {
    let dir = TempDir::new("uvs");
    std::fs::write(
        dir.0.join("quad.obj"),
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n",
    )
    .unwrap();
    let shapes = r#"
        {"type": "rectangle", "material": "m", "to_world": [{"translate": [0, 0, -3]}]},
        {"type": "obj", "material": "m", "filename": "quad.obj", "to_world": {"translate": [4, 0, 0]}},
        {"type": "obj", "material": "m", "filename": "quad.obj", "flip_tex_coords": false,
         "to_world": {"translate": [-4, 0, 0]}},
        {"type": "triangles", "material": "m", "positions": [[-1, 8, 0], [1, 8, 0], [0, 9, 0]],
         "indices": [[0, 1, 2]], "uvs": [[0, 0], [1, 0], [0.5, 1]]},
        {"type": "triangles", "material": "m", "positions": [[-1, -8, 0], [1, -8, 0], [0, -7, 0]],
         "indices": [[0, 1, 2]]},
        {"type": "sphere", "material": "m",
         "to_world": [{"rotate": {"axis": [1, 0, 0], "angle": -90}}, {"translate": [0, 20, 0]}]},
        {"type": "disk", "material": "m", "to_world": [{"scale": [2, 2, 2]}, {"translate": [10, 0, 0]}]}"#;
    let scene = from_str(&scene_json(shapes, ""), &dir.0).unwrap();
    let uv_at = |origin: DVec3| {
        let hit = scene
            .intersect(&ray(origin + 50.0 * DVec3::Z, -DVec3::Z))
            .unwrap();
        hit.uv
    };
    let near = |a: glam::DVec2, b: [f64; 2]| (a - glam::DVec2::from(b)).length() < 1e-9;
    // Rectangle: ((x + 1)/2, (y + 1)/2).
    assert!(near(uv_at(DVec3::new(0.5, -0.5, 0.0)), [0.75, 0.25]));
    // OBJ: v flipped by default (OBJ's v = 0 is an image's bottom row).
    assert!(near(uv_at(DVec3::new(4.5, -0.5, 0.0)), [0.75, 0.75]));
    assert!(near(uv_at(DVec3::new(-3.5, -0.5, 0.0)), [0.75, 0.25]));
    // Inline uvs interpolated; without them, the barycentrics (b1, b2).
    assert!(near(uv_at(DVec3::new(0.0, 8.5, 0.0)), [0.5, 0.5]));
    assert!(near(uv_at(DVec3::new(0.0, -7.5, 0.0)), [0.25, 0.5]));
    // Disk: (r, φ/2π); the point (1, 1) of the scaled disk is at r = 1/√2, φ = 45°.
    assert!(near(
        uv_at(DVec3::new(11.0, 1.0, 0.0)),
        [0.5f64.sqrt(), 0.125]
    ));
    // Sphere rotated by −90° about x: its local +z pole points to world +y,
    // so the point facing +z (world) is local −y: θ = 90°, φ = 270°.
    assert!(near(uv_at(DVec3::new(0.0, 20.0, 0.0)), [0.75, 0.5]));

    // Per-vertex uvs must match the positions; only meshes take them.
    let bad = r#"{"type": "triangles", "material": "m", "positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
        "indices": [[0, 1, 2]], "uvs": [[0, 0]]}"#;
    let e = from_str(&scene_json(bad, ""), &dir.0).err().unwrap();
    assert_eq!(e.field(), Some("shapes[0].uvs"), "{e}");
    let bad = r#"{"type": "sphere", "material": "m", "flip_tex_coords": true}"#;
    let e = from_str(&scene_json(bad, ""), &dir.0).err().unwrap();
    assert_eq!(e.field(), Some("shapes[0].flip_tex_coords"), "{e}");
}

#[test]
fn mirroring_transforms_keep_the_authored_front() {
    let dir = TempDir::new("mirror");
    let shapes = r#"{"type": "rectangle", "material": "m", "to_world": {"scale": [-1, 1, 1]}}"#;
    let scene = from_str(&scene_json(shapes, ""), &dir.0).unwrap();
    let hit = scene
        .intersect(&ray(DVec3::new(0.2, 0.3, 1.0), -DVec3::Z))
        .unwrap();
    assert!((hit.normal - DVec3::Z).length() < 1e-12);
}

#[test]
fn triangle_bvh_agrees_with_brute_force() {
    let dir = TempDir::new("soup");
    let mut rng = Pcg64::seed_from_u64(1);
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for k in 0..400 {
        let c = DVec3::new(rng.random(), rng.random(), rng.random()) * 4.0;
        for _ in 0..3 {
            let p = c + (DVec3::new(rng.random(), rng.random(), rng.random()) - 0.5) * 0.6;
            positions.push(format!("[{}, {}, {}]", p.x, p.y, p.z));
        }
        indices.push(format!("[{}, {}, {}]", 3 * k, 3 * k + 1, 3 * k + 2));
    }
    let shapes = format!(
        r#"{{"type": "triangles", "material": "m", "positions": [{}], "indices": [{}]}},
           {{"type": "sphere", "material": "m", "center": [2, 2, 2], "radius": 0.4}}"#,
        positions.join(","),
        indices.join(",")
    );
    let scene = from_str(&scene_json(&shapes, ""), &dir.0).unwrap();
    for _ in 0..2000 {
        let o = DVec3::new(rng.random(), rng.random(), rng.random()) * 5.0 - 0.5;
        let d = (DVec3::new(rng.random(), rng.random(), rng.random()) - 0.5).normalize();
        let r = ray(o, d);
        let d = r.dir;
        let brute_tri = scene
            .triangles
            .iter()
            .filter_map(|t| {
                TriangleAccel::new(t)
                    .intersect(o, d, f64::INFINITY)
                    .map(|h| h.0)
            })
            .fold(f64::INFINITY, f64::min);
        let brute = brute_tri.min(
            scene.shapes[1]
                .intersect_analytic(o, d, f64::INFINITY)
                .unwrap_or(f64::INFINITY),
        );
        match scene.intersect(&r) {
            Some(hit) => assert_eq!(hit.t, brute),
            None => assert_eq!(brute, f64::INFINITY),
        }
        assert_eq!(scene.occluded(&r), brute.is_finite());
    }
}

#[test]
fn area_sampling_is_uniform_and_lands_on_the_front_side() {
    let dir = TempDir::new("sampling");
    // Triangles of area 1 and 3; a stretched disk; a sphere.
    let shapes = r#"
        {"type": "triangles", "material": "m", "positions": [[0,0,0],[2,0,0],[0,1,0],[0,0,1],[6,0,1],[0,1,1]],
         "indices": [[0,1,2],[3,4,5]]},
        {"type": "disk", "material": "m", "to_world": [{"scale": [2, 1, 1]}, {"translate": [0, 0, -5]}]},
        {"type": "sphere", "material": "m", "center": [0, 0, 9], "radius": 2}"#;
    let scene = from_str(&scene_json(shapes, ""), &dir.0).unwrap();
    assert!((scene.shape_area(0) - 4.0).abs() < 1e-12);
    assert!((scene.shape_area(1) - 2.0 * std::f64::consts::PI).abs() < 1e-12);
    assert!((scene.shape_area(2) - 16.0 * std::f64::consts::PI).abs() < 1e-12);
    let mut rng = Pcg64::seed_from_u64(2);
    let n = 20000;
    let mut in_big = 0usize;
    let mut in_inner = 0usize;
    let mut z2 = 0.0;
    for _ in 0..n {
        let u = [rng.random(), rng.random()];
        for shape in 0..3 {
            let (p, normal, pdf) = scene.sample_shape_area(shape, u);
            assert!((pdf * scene.shape_area(shape) - 1.0).abs() < 1e-12);
            // Probing back along the normal from just in front hits the sample.
            let hit = scene.intersect(&scene.spawn_ray(p + normal * 1e-3, normal, -normal));
            let hit = hit.unwrap();
            assert_eq!(hit.shape, shape);
            assert!((hit.normal - normal).length() < 1e-9);
            assert!((hit.position - p).length() < 1e-9);
            match shape {
                0 => in_big += (p.z == 1.0) as usize,
                1 => in_inner += ((p.x / 2.0).powi(2) + p.y * p.y < 0.25) as usize,
                _ => z2 += (p.z - 9.0).powi(2) / pdf,
            }
        }
    }
    // Expected fractions 3/4 and 1/4; binomial standard error ≈ 0.003.
    assert!((in_big as f64 / n as f64 - 0.75).abs() < 0.015);
    assert!((in_inner as f64 / n as f64 - 0.25).abs() < 0.015);
    // ∫ z² dA over a sphere of radius r is 4πr⁴/3.
    let exact = 4.0 * std::f64::consts::PI * 16.0 / 3.0;
    assert!((z2 / n as f64 / exact - 1.0).abs() < 0.03);
}

#[test]
fn secondary_rays_do_not_hit_their_own_surface() {
    let scene = bundled("cornell-box.json");
    let mut rng = Pcg64::seed_from_u64(3);
    for shape in 0..scene.shape_count() {
        for _ in 0..300 {
            let (p, n, _) = scene.sample_shape_area(shape, [rng.random(), rng.random()]);
            // Random direction on the normal's side (the box interior side
            // for walls; outside for the boxes).
            let mut d = (DVec3::new(rng.random(), rng.random(), rng.random()) - 0.5).normalize();
            if d.dot(n) < 0.0 {
                d = -d;
            }
            if let Some(hit) = scene.intersect(&scene.spawn_ray(p, n, d)) {
                assert!(hit.t > 1e-6, "shape {shape} re-hit itself at t = {}", hit.t);
            }
        }
    }
    // Upper back wall points see the whole light.
    let light = scene.emitters[0].shape().expect("an area light");
    for _ in 0..500 {
        let p = DVec3::new(
            rng.random::<f64>() * 1.8 - 0.9,
            0.3 + 0.6 * rng.random::<f64>(),
            -1.0,
        );
        let (q, nq, _) = scene.sample_shape_area(light, [rng.random(), rng.random()]);
        let r = scene.spawn_ray_to(p, DVec3::Z, q, Some(nq));
        assert!(!scene.occluded(&r), "{p} → {q}");
        assert!((r.at(r.t_max) - q).length() < 1e-6);
    }
}

#[test]
fn scene_is_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<Scene>();
}

#[test]
fn exr_environment_round_trips() {
    let dir = TempDir::new("exr");
    let (w, h) = (6, 3);
    // Values exactly representable in half precision.
    let texels: Vec<[f32; 3]> = (0..w * h)
        .map(|i| [i as f32 * 0.25, 1.5, (i % 4) as f32])
        .collect();
    environment::write_exr_half(&dir.0.join("env.exr"), w, h, &texels).unwrap();
    let extra = r#", "environment": {"type": "envmap", "filename": "env.exr", "scale": 2,
                     "to_world": {"rotate": {"axis": [0, 1, 0], "angle": 90}}}"#;
    let shapes = r#"{"type": "sphere", "material": "m"}"#;
    let scene = from_str(&scene_json(shapes, extra), &dir.0).unwrap();
    let Some(Environment::Map(map)) = &scene.environment else {
        panic!("expected an environment map");
    };
    assert_eq!((map.width(), map.height()), (w, h));
    for y in 0..h {
        for x in 0..w {
            let t = texels[y * w + x];
            // The first and last rows are the poles, where u is undefined.
            let on_pole = y == 0 || y == h - 1;
            assert_eq!(
                map.texel(x, y),
                [2.0 * t[0] as f64, 2.0 * t[1] as f64, 2.0 * t[2] as f64]
            );
            // Where the lookup puts the texel (Mitsuba's: centred in u,
            // rows from pole to pole in v) it returns the texel itself.
            let d = map.uv_to_direction((x as f64 + 0.5) / w as f64, y as f64 / (h - 1) as f64);
            let r = map.radiance(d);
            for c in (0..3).filter(|_| !on_pole) {
                assert!((r[c] - map.texel(x, y)[c]).abs() < 1e-9, "{x} {y}: {r:?}");
            }
        }
    }
    // Rotated 90° about +y: map −Z (u = 0) is world −X.
    let d = map.uv_to_direction(0.0, 0.5);
    assert!((d + DVec3::X).length() < 1e-12);
}

/// Writes `files` into a fresh scenes root and loads `scene` from it.
fn load_with(tag: &str, scene: &str, files: &[(&str, &[u8])]) -> SceneError {
    let dir = TempDir::new(tag);
    let root = dir.0.join("scenes");
    std::fs::create_dir_all(root.join("sub")).unwrap();
    for (name, data) in files {
        std::fs::write(dir.0.join(name), data).unwrap();
    }
    let path = root.join("sub/scene.json");
    std::fs::write(&path, scene).unwrap();
    match Scene::load(&path, &root) {
        Ok(_) => panic!("{tag}: loaded although broken"),
        Err(e) => e,
    }
}

#[test]
fn broken_inputs_name_the_field_or_file() {
    let obj = |name: &str| {
        scene_json(
            &format!(r#"{{"type": "obj", "material": "m", "filename": "{name}"}}"#),
            "",
        )
    };
    // Missing OBJ.
    let e = load_with("missing", &obj("nothere.obj"), &[]);
    assert_eq!(e.field(), Some("shapes[0].filename"));
    assert!(e.to_string().contains("nothere.obj"), "{e}");
    // `..` escaping the scenes directory, even to a file that exists.
    let e = load_with(
        "dotdot",
        &obj("../../outside.obj"),
        &[("outside.obj", b"v 0 0 0\n")],
    );
    assert!(matches!(e, SceneError::PathEscape { .. }), "{e}");
    assert_eq!(e.field(), Some("shapes[0].filename"));
    // An absolute path outside.
    let abs = std::env::temp_dir().join("x.obj");
    let e = load_with("absolute", &obj(&abs.display().to_string()), &[]);
    assert!(matches!(e, SceneError::PathEscape { .. }), "{e}");
    // Truncated EXR.
    let dir = TempDir::new("trunc-src");
    let good = dir.0.join("good.exr");
    environment::write_exr_half(&good, 16, 8, &vec![[1.0; 3]; 128]).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let env = r#", "environment": {"type": "envmap", "filename": "sky.exr"}"#;
    let text = scene_json(r#"{"type": "sphere", "material": "m"}"#, env);
    let dir2 = TempDir::new("trunc");
    let root = dir2.0.clone();
    std::fs::write(root.join("sky.exr"), &bytes[..bytes.len() / 2]).unwrap();
    let e = from_str(&text, &root)
        .err()
        .expect("truncated EXR must fail");
    assert_eq!(e.field(), Some("environment.filename"));
    assert!(e.to_string().contains("sky.exr"), "{e}");
    // An environment transform that is not a rotation.
    let env = r#", "environment": {"type": "envmap", "filename": "sky.exr", "to_world": {"scale": [2, 2, 2]}}"#;
    let text = scene_json(r#"{"type": "sphere", "material": "m"}"#, env);
    assert_eq!(
        from_str(&text, &root).err().unwrap().field(),
        Some("environment.to_world")
    );
    // Unknown material id.
    let text = scene_json(r#"{"type": "sphere", "material": "gold"}"#, "");
    let e = from_str(&text, &root).err().unwrap();
    assert_eq!(e.field(), Some("shapes[0].material"));
    assert!(e.to_string().contains("gold"));
    // NaN in a matrix: not JSON, reported with its line and path.
    let text = scene_json(
        r#"{"type": "rectangle", "material": "m",
            "to_world": {"matrix": [[1, 0, 0, 0], [0, 1, NaN, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}}"#,
        "",
    );
    let nan_line = text.lines().position(|l| l.contains("NaN")).unwrap() + 1;
    let e = from_str(&text, &root).err().unwrap();
    let SceneError::Syntax { line, field, .. } = &e else {
        panic!("{e}")
    };
    assert_eq!(*line, nan_line);
    assert!(field.starts_with("shapes[0].to_world"), "{field}");
    // Unknown field.
    let text = scene_json(
        r#"{"type": "sphere", "material": "m", "radius": 1, "colour": 3}"#,
        "",
    );
    let e = from_str(&text, &root).err().unwrap();
    assert!(e.to_string().contains("colour"), "{e}");
    assert_eq!(e.field(), Some("shapes[0].colour"));
    // A field that belongs to another shape type.
    let text = scene_json(r#"{"type": "cube", "material": "m", "radius": 1}"#, "");
    assert_eq!(
        from_str(&text, &root).err().unwrap().field(),
        Some("shapes[0].radius")
    );
    // Singular transform and non-similarity sphere.
    let text = scene_json(
        r#"{"type": "cube", "material": "m", "to_world": [{"scale": [1, 0, 1]}]}"#,
        "",
    );
    assert_eq!(
        from_str(&text, &root).err().unwrap().field(),
        Some("shapes[0].to_world")
    );
    // Non-similarity spheres and cylinders, a cylinder without an axis.
    for (shape, field) in [
        (
            r#"{"type": "sphere", "material": "m", "to_world": [{"scale": [1, 2, 1]}]}"#,
            "shapes[0].to_world",
        ),
        (
            r#"{"type": "cylinder", "material": "m", "to_world": [{"scale": [1, 1, 3]}]}"#,
            "shapes[0].to_world",
        ),
        (
            r#"{"type": "cylinder", "material": "m", "p0": [1, 2, 3], "p1": [1, 2, 3]}"#,
            "shapes[0].p1",
        ),
        (
            r#"{"type": "cylinder", "material": "m", "radius": 0}"#,
            "shapes[0].radius",
        ),
    ] {
        let text = scene_json(shape, "");
        assert_eq!(from_str(&text, &root).err().unwrap().field(), Some(field));
    }
    // Out-of-range index in an inline mesh.
    let text = scene_json(
        r#"{"type": "triangles", "material": "m", "positions": [[0,0,0],[1,0,0],[0,1,0]], "indices": [[0, 1, 3]]}"#,
        "",
    );
    assert_eq!(
        from_str(&text, &root).err().unwrap().field(),
        Some("shapes[0].indices[0][2]")
    );
    // Energy-creating material and absurd resolution.
    let text = r#"{"materials": [{"id": "m", "type": "glossy", "diffuse": [0.6, 0.5, 0.5],
                    "specular": [0.6, 0.1, 0.1], "exponent": 20}], "shapes": [],
                   "camera": {"fov": 40, "width": 8, "height": 8, "origin": [0,0,1], "target": [0,0,0], "up": [0,1,0]}}"#;
    assert_eq!(
        from_str(text, &root).err().unwrap().field(),
        Some("materials[0].specular[0]")
    );
    let text = r#"{"shapes": [], "camera": {"fov": 40, "width": 100000, "height": 8,
                   "origin": [0,0,1], "target": [0,0,0], "up": [0,1,0]}}"#;
    assert_eq!(
        from_str(text, &root).err().unwrap().field(),
        Some("camera.width")
    );
}

#[test]
fn bundled_sky_and_mesh_scenes_load() {
    let sky = bundled("sky.json");
    // The committed maps are the generator's output (to half precision).
    let (w, h) = generate::SKY_SIZE;
    for (scene, radiance) in [
        (&sky, generate::sky_radiance as fn(_) -> _),
        (&bundled("overcast.json"), generate::overcast_radiance),
    ] {
        let Some(Environment::Map(map)) = &scene.environment else {
            panic!("no environment map");
        };
        assert_eq!((map.width(), map.height()), generate::SKY_SIZE);
        let fresh = generate::map_texels(w, h, radiance);
        for (i, t) in fresh.iter().enumerate() {
            let stored = map.texel(i % w, i / w);
            for c in 0..3 {
                assert!(
                    (stored[c] - t[c] as f64).abs() <= 1e-3 * t[c] as f64 + 1e-4,
                    "texel {i}"
                );
            }
        }
    }
    assert!(
        sky.materials
            .iter()
            .any(|m| matches!(m, Material::Glossy(_)))
    );
    assert!(
        sky.materials
            .iter()
            .any(|m| matches!(m, Material::Diffuse(_)))
    );
    // The camera's centre ray lands on something.
    assert!(
        sky.intersect(&sky.camera.generate_ray(160.0, 120.0))
            .is_some()
    );

    let mesh = bundled("mesh.json");
    assert!(
        mesh.triangle_count() >= 100_000,
        "{}",
        mesh.triangle_count()
    );
    for o in [
        DVec3::new(0.3, 2.5, 0.2),
        DVec3::new(-3.0, 0.1, 0.4),
        DVec3::new(0.2, -0.5, 3.0),
    ] {
        let hit = mesh.intersect(&ray(o, -o)).unwrap();
        assert_eq!(hit.shape, 1);
        assert!(
            hit.normal.dot(hit.position) > 0.0,
            "blob normals face outwards: {hit:?}"
        );
    }
}

#[test]
fn vertex_normals_set_the_front_and_interpolate() {
    let dir = TempDir::new("normals");
    // Wound to face +z, but the vertex normals lean towards -z: the front
    // follows the vertex normals.
    let shapes = r#"{"type": "triangles", "material": "m",
        "positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "indices": [[0, 1, 2]],
        "normals": [[0, 0, -1], [1, 0, -1], [0, 1, -1]]}"#;
    let scene = from_str(&scene_json(shapes, ""), &dir.0).unwrap();
    let hit = scene
        .intersect(&ray(DVec3::new(0.5, 0.25, 1.0), -DVec3::Z))
        .unwrap();
    assert!((hit.normal + DVec3::Z).length() < 1e-12);
    // Barycentrics (0.25, 0.5, 0.25) weight the three normals.
    let n0 = DVec3::new(0.0, 0.0, -1.0);
    let n1 = DVec3::new(1.0, 0.0, -1.0).normalize();
    let n2 = DVec3::new(0.0, 1.0, -1.0).normalize();
    let expected = (n0 * 0.25 + n1 * 0.5 + n2 * 0.25).normalize();
    assert!((hit.shading_normal - expected).length() < 1e-12, "{hit:?}");
    let (_, n, _) = scene.sample_shape_area(0, [0.3, 0.6]);
    assert!((n + DVec3::Z).length() < 1e-12);
}

#[test]
fn a_mesh_file_is_read_once_per_scene_and_sized_before_building() {
    let dir = scenes_dir();
    let blob = |count: usize| {
        let shapes: Vec<String> = (0..count)
            .map(|i| {
                format!(
                    r#"{{"type": "obj", "filename": "meshes/blob.obj", "material": "m",
                        "to_world": [{{"translate": [{i}, 0, 0]}}]}}"#
                )
            })
            .collect();
        scene_json(&shapes.join(","), "")
    };
    // Three instances of one file: three placed copies of its triangles.
    let scene = from_str(&blob(3), &dir).unwrap();
    assert_eq!(scene.triangle_count(), 3 * 101_760);
    let (min, max) = scene.bounds();
    assert!(max.x - min.x > 2.0, "{min} {max}");
    // Retained bytes are within the estimate the loader checks against.
    assert!(scene.heap_bytes() <= triangle_bytes(scene.triangle_count()) + (1 << 20));
    assert!(scene.heap_bytes() >= scene.triangle_count() as u64 * 150);

    // Enough instances to pass MAX_SCENE_MEMORY_BYTES: refused while sizing,
    // before any triangle is placed, naming the limit and the shape that
    // passes it.
    let too_many = (MAX_SCENE_MEMORY_BYTES / (101_760 * TRIANGLE_BYTES)) as usize + 1;
    let e = from_str(&blob(too_many), &dir).err().unwrap();
    assert!(e.field().unwrap().starts_with("shapes["), "{e}");
    assert!(e.to_string().contains("MAX_SCENE_MEMORY_BYTES"), "{e}");
}

#[test]
fn mesh_files_are_shared_by_canonical_path() {
    let root = scenes_dir().canonicalize().unwrap();
    let files = files::Files::new(&root, &root).unwrap();
    let a = files.resolve("meshes/blob.obj", "f").unwrap();
    let b = files.resolve("./meshes/../meshes/blob.obj", "f").unwrap();
    assert_eq!(a, b);
    let obj = format::ShapeKind::named("obj")
        .unwrap()
        .plugin()
        .mesh_file
        .unwrap();
    let wanted = [a, b].map(|p| ((p, 0), obj, "f".to_string()));
    let budget = budget::Budget::new(&LoadLimits::default());
    let meshes = loader::MeshFiles::read_all(wanted.to_vec(), MAX_TRIANGLES, &budget).unwrap();
    assert_eq!(meshes.len(), 1);
}

#[test]
fn special_scene_and_mesh_files_are_refused() {
    let dir = TempDir::new("special");
    let fifo = |name: &str| {
        std::process::Command::new("mkfifo")
            .arg(dir.0.join(name))
            .status()
            .is_ok_and(|s| s.success())
    };
    if !fifo("scene.json") || !fifo("mesh.obj") {
        eprintln!("mkfifo unavailable: skipped");
        return;
    }
    // Opening either for reading would block until a writer appears.
    let e = Scene::load(&dir.0.join("scene.json"), &dir.0)
        .err()
        .unwrap();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let shapes = r#"{"type": "obj", "filename": "mesh.obj", "material": "m"}"#;
    let e = from_str(&scene_json(shapes, ""), &dir.0).err().unwrap();
    assert_eq!(e.field(), Some("shapes[0].filename"));
    assert!(e.to_string().contains("not a regular file"), "{e}");
}

mod fuzz {
    //! The JSON scene parser on random and mutated documents: never a
    //! panic, and errors are messages of bounded size.

    use proptest::prelude::*;

    use super::*;

    fn check(text: &str) {
        if let Err(e) = Scene::from_json_str(text, &scenes_dir(), &scenes_dir()) {
            let message = e.to_string();
            assert!(!message.is_empty());
            assert!(message.len() < 4096, "{} bytes of message", message.len());
        }
    }

    /// Shape entries, valid and not, for random documents.
    const SHAPES: &[&str] = &[
        r#"{"type": "cube", "material": "m"}"#,
        r#"{"type": "sphere", "material": "m", "radius": 0.5}"#,
        r#"{"type": "disk", "material": "m", "to_world": [{"scale": [1, 2, 1]}]}"#,
        r#"{"type": "rectangle", "material": "m", "emitter": {"type": "area", "radiance": [1, 1, 1]}}"#,
        r#"{"type": "triangles", "material": "m", "positions": [[0,0,0],[1,0,0],[0,1,0]], "indices": [[0,1,2]]}"#,
        r#"{"type": "triangles", "material": "m", "positions": [[0,0,0]], "indices": [[0,1,2]]}"#,
        r#"{"type": "obj", "material": "m", "filename": "missing.obj"}"#,
        r#"{"type": "obj", "material": "m", "filename": "../../etc/passwd"}"#,
        r#"{"type": "cube", "material": "nope"}"#,
        r#"{"type": "cube", "material": "m", "material": "m"}"#,
        r#"{"type": "sphere", "material": "m", "radius": -1}"#,
        r#"{"type": "cylinder", "material": "m", "p0": [0, 0, 0], "p1": [0, 2, 0], "radius": 0.5}"#,
        r#"{"type": "cylinder", "material": "m", "p1": [0, 0, 0]}"#,
    ];

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            check(&String::from_utf8_lossy(&bytes));
        }

        #[test]
        fn random_shape_lists_never_panic(picks in proptest::collection::vec(0..SHAPES.len(), 0..16)) {
            let shapes: Vec<&str> = picks.iter().map(|&i| SHAPES[i]).collect();
            check(&scene_json(&shapes.join(","), ""));
        }

        #[test]
        fn mutated_cornell_box_never_panics(
            edits in proptest::collection::vec((any::<prop::sample::Index>(), 0..4u8, any::<char>()), 1..8),
        ) {
            let original = std::fs::read_to_string(scenes_dir().join("cornell-box.json")).unwrap();
            check(&super::mutated_text(&original, edits));
        }
    }
}

#[test]
fn emitter_textures_count_in_the_scenes_bytes_and_budget() {
    let dir = TempDir::new("emitter-texture");
    image::RgbImage::from_pixel(128, 64, image::Rgb([200, 100, 50]))
        .save(dir.0.join("glow.png"))
        .unwrap();
    let text = scene_json(
        r#"{"type": "rectangle", "material": "m",
            "emitter": {"type": "area", "radiance": {"type": "bitmap", "filename": "glow.png"}}}"#,
        "",
    );
    let scene = from_str(&text, &dir.0).unwrap();
    let texels = 128 * 64 * 12;
    assert!(scene.heap_bytes() >= texels, "{}", scene.heap_bytes());
    // Decoding it would take the load past its budget: refused first.
    let limits = LoadLimits {
        max_bytes: texels,
        budget: "scenes.max_scene_bytes",
        ..LoadLimits::default()
    };
    let loaded = loader::from_json_str(&text, "glow.json", &dir.0, &dir.0, &limits);
    let Err(e) = loaded else {
        panic!("loaded within {texels} bytes")
    };
    assert!(matches!(e, SceneError::OverBudget { .. }), "{e}");
    assert_eq!(e.field(), Some("shapes[0].emitter.radiance.filename"));
}

#[test]
fn nested_materials_may_name_earlier_ones_by_id() {
    let doc = |materials: &str| {
        format!(
            r#"{{ "materials": [{materials}],
                 "shapes": [{{"type": "rectangle", "material": "top"}}],
                 "camera": {{"fov": 40, "width": 8, "height": 8,
                             "origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}} }}"#
        )
    };
    let base = r#"{"id": "base", "type": "diffuse", "reflectance": 0.5}"#;
    let scene = from_str(
        &doc(&format!(
            r#"{base}, {{"id": "top", "type": "blendbsdf", "bsdf": ["base", {{"type": "conductor"}}]}}"#
        )),
        &scenes_dir(),
    )
    .unwrap();
    let Material::Blend(crate::scene::material::blend::BlendMaterial { bsdfs, .. }) =
        &scene.materials[1]
    else {
        panic!("{:?}", scene.materials[1])
    };
    assert_eq!(*bsdfs[0], scene.materials[0]);
    // Only materials declared before may be named.
    let e = from_str(
        &doc(&format!(
            r#"{{"id": "top", "type": "twosided", "bsdf": ["base"]}}, {base}"#
        )),
        &scenes_dir(),
    )
    .err()
    .unwrap();
    assert_eq!(e.field(), Some("materials[0].bsdf[0]"), "{e}");
}

/// A shape's `sensor` makes it an irradiance meter, named by the shape's id
/// (or its field path); its points lie on the shape with its front normal.
#[test]
fn irradiance_meters_are_shapes_with_a_sensor() {
    let dir = TempDir::new("meters");
    let text = scene_json(
        r#"{"type": "disk", "material": "m", "id": "desk", "sensor": {"type": "irradiancemeter"},
            "to_world": [{"scale": [0.1, 0.1, 0.1]}, {"translate": [0, 0, -2]}]},
           {"type": "rectangle", "material": "m", "sensor": {"type": "irradiancemeter"}}"#,
        "",
    );
    let scene = from_str(&text, &dir.0).unwrap();
    let ids: Vec<_> = scene.meters.iter().map(|m| m.id.as_str()).collect();
    assert_eq!(ids, ["desk", "shapes[1]"]);
    let points = scene.meter_points(&scene.meters[0]);
    assert_eq!(points.len(), meter::METER_GRID * meter::METER_GRID);
    for (p, n) in points {
        assert!((p.z + 2.0).abs() < 1e-12 && p.truncate().length() < 0.1);
        assert!((n - DVec3::Z).length() < 1e-12);
    }
    let bad = scene_json(
        r#"{"type": "disk", "material": "m", "sensor": {"type": "radiancemeter"}}"#,
        "",
    );
    let e = from_str(&bad, &dir.0).err().unwrap();
    assert!(e.to_string().contains("radiancemeter"), "{e}");
    assert_eq!(e.field(), Some("shapes[0].sensor.type"));
}

/// A shape's `type` reads and writes as the derived enum it replaced did:
/// serde's message lists the registry's names, and the document (which
/// the digest hashes) serialises each kind as its name.
#[test]
fn shape_types_are_the_registry_names() {
    let dir = TempDir::new("shape-types");
    let bad = r#"{"type": "spheroid", "material": "m"}"#;
    let e = from_str(&scene_json(bad, ""), &dir.0).err().unwrap();
    assert!(
        e.to_string().contains(
            "unknown variant `spheroid`, expected one of `rectangle`, `cube`, `sphere`, `disk`, `cylinder`, `obj`, `ply`, `serialized`, `triangles`"
        ),
        "{e}"
    );
    for name in crate::scene::shape::plugin_names() {
        let kind: format::ShapeKind = serde_json::from_str(&format!("{name:?}")).unwrap();
        assert_eq!(serde_json::to_string(&kind).unwrap(), format!("{name:?}"));
    }
}
