//! Procedural assets for the bundled scenes, written by the project's own
//! code: a sky environment map with a sun-like lobe, a smooth overcast sky
//! without one, a dusk sky (Radiance HDR), a floor-tile texture (sRGB PNG)
//! and a displaced sphere mesh.
//! `cargo run --example generate_scene_assets` regenerates `scenes/sky.exr`,
//! `scenes/overcast.exr`, `scenes/dusk.hdr`, `scenes/textures/tiles.png`
//! and `scenes/meshes/blob.obj`.

use std::f64::consts::PI;
use std::path::Path;

use glam::{DMat3, DVec3};

use super::environment::{EnvironmentMap, write_exr_half};
use super::mesh::{MeshData, write_obj};

/// Size of the bundled sky map (half-float RGB, ~50 KB).
pub const SKY_SIZE: (usize, usize) = (128, 64);
/// Subdivision of the bundled blob: 320 × 160 gives 101 760 triangles.
pub const BLOB_SEGMENTS: (usize, usize) = (320, 160);

/// Unit direction of the sun in the map frame (+Y up): 35° above the horizon.
pub fn sun_direction() -> DVec3 {
    let elevation = 35f64.to_radians();
    let azimuth = 60f64.to_radians();
    DVec3::new(
        azimuth.sin() * elevation.cos(),
        elevation.sin(),
        -azimuth.cos() * elevation.cos(),
    )
}

/// Radiance of the procedural sky along map direction `d` (unit), W/(m²·sr):
/// a blue-to-white gradient above the horizon, dim brown ground below and a
/// sun lobe `∝ exp(k (cos γ − 1))` of about 2° angular radius.
pub fn sky_radiance(d: DVec3) -> [f64; 3] {
    let up = d.y.max(0.0);
    let w = (1.0 - up).powi(4);
    let zenith = [0.12, 0.25, 0.7];
    let horizon = [0.75, 0.8, 0.9];
    let ground = [0.18, 0.14, 0.1];
    // Smooth step across the horizon avoids a hard edge within a texel row.
    let g = ((-d.y) * 20.0).clamp(0.0, 1.0);
    let cos_gamma = d.dot(sun_direction());
    let sun = 3000.0 * (800.0 * (cos_gamma - 1.0)).exp();
    let sun_colour = [1.0, 0.9, 0.75];
    std::array::from_fn(|c| {
        let sky = zenith[c] * (1.0 - w) + horizon[c] * w;
        sky * (1.0 - g) + ground[c] * g + sun * sun_colour[c] * (1.0 - g)
    })
}

/// Radiance of the procedural overcast sky along map direction `d` (unit),
/// W/(m²·sr): a smooth, sunless environment. An overcast sky brightening
/// towards the zenith (`(1 + 2 cos θ)/3`, the CIE overcast gradation), a
/// broad warm glow where the sun hides behind the clouds (about 35° wide),
/// and a dim ground below a horizon blurred over about 10°. Its relative
/// variance over the sphere is about 0.5, so `auto` integrates it through
/// the hemisphere with the environment prior (docs/math.md §14).
pub fn overcast_radiance(d: DVec3) -> [f64; 3] {
    let cloud = [0.85, 0.9, 1.0];
    let glow_colour = [1.0, 0.8, 0.55];
    let ground = [0.16, 0.15, 0.13];
    let up = d.y.max(0.0);
    let gradation = (1.0 + 2.0 * up) / 3.0;
    let glow_direction = DVec3::new(-0.55, 0.45, -0.7).normalize();
    let glow = 1.2 * (4.0 * (d.dot(glow_direction) - 1.0)).exp();
    // 0 above the horizon, 1 from 10° below it, smooth in between.
    let t = (-d.y / 10f64.to_radians().sin()).clamp(0.0, 1.0);
    let g = t * t * (3.0 - 2.0 * t);
    std::array::from_fn(|c| {
        let sky = 1.4 * gradation * cloud[c] + glow * glow_colour[c];
        sky * (1.0 - g) + ground[c] * g
    })
}

/// Radiance of the procedural dusk sky along map direction `d` (unit),
/// W/(m²·sr): deep blue at the zenith, a warm horizon brightest where the
/// sun has just set (a glow about 40° wide, the sun itself below the
/// horizon), and a dark ground below a horizon blurred over about 5°. Dim
/// enough (irradiance ≈ 1 W/m² on the ground) that the studio scene's
/// point and spot lights dominate where they shine.
pub fn dusk_radiance(d: DVec3) -> [f64; 3] {
    let zenith = [0.05, 0.09, 0.25];
    let horizon = [0.55, 0.38, 0.3];
    let glow_colour = [1.4, 0.6, 0.22];
    let ground = [0.04, 0.035, 0.03];
    let up = d.y.max(0.0);
    let w = (1.0 - up).powi(3);
    let set = DVec3::new(0.8, -0.05, -0.6).normalize();
    let glow = (3.0 * (d.dot(set) - 1.0)).exp() * (1.0 - up).powi(2);
    let t = (-d.y / 5f64.to_radians().sin()).clamp(0.0, 1.0);
    let g = t * t * (3.0 - 2.0 * t);
    std::array::from_fn(|c| {
        let sky = zenith[c] * (1.0 - w) + horizon[c] * w + glow * glow_colour[c];
        sky * (1.0 - g) + ground[c] * g
    })
}

/// Side of the bundled floor-tile texture in texels.
pub const TILES_SIZE: u32 = 512;

/// Linear reflectance of the floor-tile texture at texel `(x, y)` of a
/// `size`² image: 8 × 8 square tiles alternating terracotta and cream, each
/// tile's colour varied by a few per cent, with grey grout lines between
/// them.
pub fn tiles_reflectance(x: u32, y: u32, size: u32) -> [f64; 3] {
    let tile = size / 8;
    let (i, j) = (x / tile, y / tile);
    let (u, v) = (x % tile, y % tile);
    let grout = tile / 24 + 1;
    if u < grout || v < grout {
        return [0.42, 0.41, 0.39];
    }
    let base = if (i + j) % 2 == 0 {
        [0.62, 0.3, 0.18]
    } else {
        [0.82, 0.75, 0.6]
    };
    // A tile's own shade from a hash of its index: within ±6 %.
    let hash = (i.wrapping_mul(73_856_093) ^ j.wrapping_mul(19_349_663)) % 1000;
    let shade = 0.94 + 0.12 * f64::from(hash) / 1000.0;
    base.map(|b| b * shade)
}

/// The floor-tile texture as 8-bit sRGB texels, `TILES_SIZE`² RGB.
fn tiles_texture() -> image::RgbImage {
    let encode = |linear: f64| {
        // The sRGB transfer function (IEC 61966-2-1).
        let s = if linear <= 0.003_130_8 {
            12.92 * linear
        } else {
            1.055 * linear.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round().clamp(0.0, 255.0) as u8
    };
    image::RgbImage::from_fn(TILES_SIZE, TILES_SIZE, |x, y| {
        image::Rgb(tiles_reflectance(x, y, TILES_SIZE).map(encode))
    })
}

/// Writes `texels` (`width` × `height`, rows from the top) as a Radiance
/// HDR (RGBE) file.
fn write_hdr(path: &Path, width: usize, height: usize, texels: &[[f32; 3]]) -> anyhow::Result<()> {
    let rgb: Vec<image::Rgb<f32>> = texels.iter().map(|&t| image::Rgb(t)).collect();
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    image::codecs::hdr::HdrEncoder::new(file).encode(&rgb, width, height)?;
    Ok(())
}

/// Texels of a map of `radiance`, each the average of 4×4 directions inside
/// it so narrow features are not aliased.
pub fn map_texels(width: usize, height: usize, radiance: fn(DVec3) -> [f64; 3]) -> Vec<[f32; 3]> {
    let frame = EnvironmentMap::new(
        width,
        height,
        vec![[0.0; 3]; width * height],
        1.0,
        DMat3::IDENTITY,
    );
    let n = 4;
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let mut sum = [0.0f64; 3];
            for j in 0..n {
                for i in 0..n {
                    let u = (x as f64 + (i as f64 + 0.5) / n as f64) / width as f64;
                    let v = (y as f64 + (j as f64 + 0.5) / n as f64) / height as f64;
                    let r = radiance(frame.uv_to_direction(u, v));
                    (0..3).for_each(|c| sum[c] += r[c]);
                }
            }
            out.push(sum.map(|s| (s / (n * n) as f64) as f32));
        }
    }
    out
}

/// Radius of the blob at polar angle θ and azimuth φ: a unit sphere with
/// three octaves of smooth bumps, each vanishing at the poles (θ = 0, π) so
/// the surface stays single-valued there.
fn blob_radius(theta: f64, phi: f64) -> f64 {
    1.0 + 0.06 * (5.0 * phi).sin() * (4.0 * theta).sin()
        + 0.03 * (13.0 * phi + 2.0 * theta).sin() * (9.0 * theta).sin()
        + 0.015 * (31.0 * phi).sin() * (27.0 * theta).sin()
}

/// Closed displaced sphere with `segments` azimuthal steps and `rings`
/// polar steps: `2·segments·(rings − 1)` triangles, wound outwards.
pub fn displaced_sphere(segments: usize, rings: usize) -> MeshData {
    let point = |theta: f64, phi: f64| {
        let r = blob_radius(theta, phi);
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            -theta.sin() * phi.sin(),
        ) * r
    };
    let mut positions = vec![point(0.0, 0.0)];
    for ring in 1..rings {
        let theta = PI * ring as f64 / rings as f64;
        for s in 0..segments {
            positions.push(point(theta, 2.0 * PI * s as f64 / segments as f64));
        }
    }
    positions.push(point(PI, 0.0));
    let south = (positions.len() - 1) as u32;
    let at = |ring: usize, s: usize| (1 + (ring - 1) * segments + s % segments) as u32;
    let mut indices = Vec::new();
    for s in 0..segments {
        indices.push([0, at(1, s), at(1, s + 1)]);
        for ring in 1..rings - 1 {
            let (a, b) = (at(ring, s), at(ring, s + 1));
            let (c, d) = (at(ring + 1, s), at(ring + 1, s + 1));
            indices.push([a, c, d]);
            indices.push([a, d, b]);
        }
        indices.push([at(rings - 1, s), south, at(rings - 1, s + 1)]);
    }
    MeshData {
        positions,
        indices,
        normals: None,
        uvs: None,
    }
}

/// Writes `sky.exr`, `overcast.exr`, `dusk.hdr`, `textures/tiles.png` and
/// `meshes/blob.obj` under `dir` (normally `scenes/`).
pub fn write_bundled_assets(dir: &Path) -> anyhow::Result<()> {
    let (w, h) = SKY_SIZE;
    write_hdr(
        &dir.join("dusk.hdr"),
        2 * w,
        2 * h,
        &map_texels(2 * w, 2 * h, dusk_radiance),
    )?;
    std::fs::create_dir_all(dir.join("textures"))?;
    tiles_texture().save(dir.join("textures/tiles.png"))?;
    write_exr_half(&dir.join("sky.exr"), w, h, &map_texels(w, h, sky_radiance))?;
    write_exr_half(
        &dir.join("overcast.exr"),
        w,
        h,
        &map_texels(w, h, overcast_radiance),
    )?;
    std::fs::create_dir_all(dir.join("meshes"))?;
    let (segments, rings) = BLOB_SEGMENTS;
    write_obj(
        &dir.join("meshes/blob.obj"),
        &displaced_sphere(segments, rings),
        5,
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blob_is_closed_and_wound_outwards() {
        let mesh = displaced_sphere(24, 12);
        assert_eq!(mesh.indices.len(), 2 * 24 * 11);
        // Every edge is shared by exactly two triangles in opposite directions.
        let mut edges = std::collections::HashMap::new();
        for t in &mesh.indices {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1);
            assert_eq!(edges.get(&(b, a)), Some(&1));
        }
    }

    #[test]
    fn sky_is_brightest_towards_the_sun() {
        let texels = map_texels(32, 16, sky_radiance);
        let frame = EnvironmentMap::new(32, 16, texels.clone(), 1.0, DMat3::IDENTITY);
        let brightest = (0..texels.len())
            .max_by(|&a, &b| texels[a][0].total_cmp(&texels[b][0]))
            .unwrap();
        let (x, y) = (brightest % 32, brightest / 32);
        let d = frame.uv_to_direction((x as f64 + 0.5) / 32.0, (y as f64 + 0.5) / 16.0);
        assert!(d.dot(sun_direction()) > 0.98, "{d}");
        assert!(frame.radiance(DVec3::Y)[2] > frame.radiance(-DVec3::Y)[2]);
    }

    #[test]
    fn overcast_is_smooth_and_sky_is_not() {
        use crate::scene::Environment;
        let relative_variance = |radiance| {
            let map =
                EnvironmentMap::new(64, 32, map_texels(64, 32, radiance), 1.0, DMat3::IDENTITY);
            crate::render::environment_sampling::environment_relative_variance(&Environment::Map(
                map,
            ))
        };
        let overcast = relative_variance(overcast_radiance);
        let sky = relative_variance(sky_radiance);
        assert!(overcast < 1.0, "{overcast}");
        assert!(sky > 100.0, "{sky}");
    }
}
