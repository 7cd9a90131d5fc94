//! Light arriving from infinitely far away: a constant colour or a lat-long
//! environment map read from an image (EXR, Radiance HDR, or an sRGB PNG
//! or JPEG, `scene::bitmap`).
//!
//! ## Lat-long convention (Mitsuba 3's `envmap`)
//! In the map's own frame +Y is up. A direction `d` has polar angle
//! `θ = acos(d.y)` from +Y and azimuth `φ = atan2(d.x, -d.z)`, and
//! `u = φ / 2π` (wrapped to [0, 1)), `v = θ / π`. Conversely
//! `d = (sin φ sin θ, cos θ, −cos φ sin θ)`. Row `y = 0` of the image is the
//! top (towards +Y); column `x = 0` starts at `φ = 0`, i.e. towards −Z.
//! The map's `to_world` rotation carries map directions into the world.
//!
//! The radiance is interpolated bilinearly between texels as Mitsuba 3's
//! `envmap` does: periodic in `u` with texel centres at `(x + ½)/w`, and
//! clamped in `v` with the first and last rows on the poles (row `y` at
//! `v = y/(h − 1)`). Importance sampling picks cells of the (u, v) square
//! by the interpolated radiance's mean over them (`render::
//! environment_sampling`). Solid angle and the (u, v)
//! square are related by `dω = 2π² sin θ du dv`.

use std::path::Path;

use glam::{DMat3, DVec3};

use super::error::SceneError;

/// Largest accepted map width and height in texels.
pub const MAX_ENVMAP_SIDE: usize = 16384;
/// Largest accepted number of texels: 8192 × 4096, an "8K" HDR panorama.
/// The decoded map takes 12 bytes a texel (384 MiB at most), and decoding
/// peaks at a few times that, whatever the file's compressed size.
pub const MAX_ENVMAP_TEXELS: usize = 1 << 25;

/// Largest accepted EXR file, bytes: the largest accepted map
/// ([`MAX_ENVMAP_TEXELS`]) stored uncompressed as f32 RGB.
pub const MAX_EXR_BYTES: u64 = (MAX_ENVMAP_TEXELS as u64) * 12 + (1 << 20);

/// Distant illumination; `Scene::environment` is `None` for black.
#[derive(Clone, Debug)]
pub enum Environment {
    /// The same radiance, W/(m²·sr), from every direction.
    Constant {
        radiance: [f64; 3],
    },
    Map(EnvironmentMap),
}

impl Environment {
    /// Radiance arriving along `-world_dir`, i.e. seen when looking towards
    /// `world_dir` (unit length).
    pub fn radiance(&self, world_dir: DVec3) -> [f64; 3] {
        match self {
            Environment::Constant { radiance } => *radiance,
            Environment::Map(map) => map.radiance(world_dir),
        }
    }
}

/// An RGB lat-long image, a scale and a rotation; see the module docs.
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Row-major texels as stored in the file (f32 is what EXR holds at most).
    texels: Vec<[f32; 3]>,
    /// Multiplier applied to every texel.
    scale: f64,
    /// World → map rotation (transpose of `to_world`).
    world_to_map: DMat3,
}

impl EnvironmentMap {
    /// A map from row-major `texels` (`width × height`, top row first).
    /// `to_world` must be a rotation; the loader checks this.
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<[f32; 3]>,
        scale: f64,
        to_world: DMat3,
    ) -> Self {
        debug_assert_eq!(texels.len(), width * height);
        Self {
            width,
            height,
            texels,
            scale,
            world_to_map: to_world.transpose(),
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    /// Bytes the texels hold on the heap.
    pub fn heap_bytes(&self) -> u64 {
        (self.texels.capacity() * std::mem::size_of::<[f32; 3]>()) as u64
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Scaled radiance of texel (x, y), W/(m²·sr); row 0 is the top.
    pub fn texel(&self, x: usize, y: usize) -> [f64; 3] {
        let t = self.texels[y * self.width + x];
        [
            t[0] as f64 * self.scale,
            t[1] as f64 * self.scale,
            t[2] as f64 * self.scale,
        ]
    }

    /// Map → world rotation.
    pub fn to_world(&self) -> DMat3 {
        self.world_to_map.transpose()
    }

    /// Radiance seen looking towards `world_dir` (unit length), bilinear
    /// between the four texels around it (module docs).
    pub fn radiance(&self, world_dir: DVec3) -> [f64; 3] {
        let (u, v) = self.direction_to_uv(world_dir);
        self.radiance_at_uv(u, v)
    }

    /// Radiance at map coordinates `(u, v)` ∈ [0, 1]², bilinear between the
    /// four texels around them (module docs).
    pub fn radiance_at_uv(&self, u: f64, v: f64) -> [f64; 3] {
        let x = u * self.width as f64 - 0.5;
        let y = v * (self.height - 1) as f64;
        let (fx, fy) = (x.floor(), y.floor());
        let column = |i: f64| (i as i64).rem_euclid(self.width as i64) as usize;
        let row = |j: f64| (j.max(0.0) as usize).min(self.height - 1);
        let (x0, x1, y0, y1) = (column(fx), column(fx + 1.0), row(fy), row(fy + 1.0));
        let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].map(|(i, j)| self.texel(i, j));
        super::bilinear::blend(corners, glam::DVec2::new(x - fx, y - fy))
    }

    /// (u, v) ∈ [0, 1)×[0, 1] of a unit world direction.
    pub fn direction_to_uv(&self, world_dir: DVec3) -> (f64, f64) {
        let d = self.world_to_map * world_dir;
        let mut u = d.x.atan2(-d.z) / std::f64::consts::TAU;
        if u < 0.0 {
            u += 1.0;
        }
        if u >= 1.0 {
            u = 0.0;
        }
        let v = d.y.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
        (u, v)
    }

    /// Unit world direction of (u, v); inverse of [`Self::direction_to_uv`].
    pub fn uv_to_direction(&self, u: f64, v: f64) -> DVec3 {
        let (sin_phi, cos_phi) = (u * std::f64::consts::TAU).sin_cos();
        let (sin_theta, cos_theta) = (v * std::f64::consts::PI).sin_cos();
        let d = DVec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta);
        self.world_to_map.transpose() * d
    }
}

/// Reads the RGB channels of the first layer that has them of an EXR file:
/// `(width, height, texels)`, top row first. Errors name `field` and the
/// file; the size of every part is checked from the headers, and the size
/// of the part that will be read passed to `reserve`, before any pixel
/// memory is allocated.
pub(crate) fn read_exr(
    path: &Path,
    field: &str,
    reserve: &dyn Fn(usize, usize) -> Result<(), SceneError>,
) -> Result<(usize, usize, Vec<[f32; 3]>), SceneError> {
    use exr::prelude::*;
    let err = |message: String| SceneError::file(field, path, message);
    let open = || {
        super::read::open_capped(path, MAX_EXR_BYTES)
            .map(std::io::BufReader::new)
            .map_err(|e| err(format!("cannot open: {e}")))
    };
    let meta = exr::meta::MetaData::read_from_buffered(open()?, false)
        .map_err(|e| err(format!("not a readable EXR file: {e}")))?;
    crate::image::check_exr_parts(&meta, MAX_ENVMAP_SIDE, MAX_ENVMAP_TEXELS).map_err(err)?;
    // The decoder reads the first part with RGB channels; reserving the
    // largest part's size is simpler and never less.
    let (width, height) = meta
        .headers
        .iter()
        .map(|h| (h.layer_size.width(), h.layer_size.height()))
        .max_by_key(|(w, h)| w * h)
        .unwrap_or_default();
    reserve(width, height)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |resolution, _| (resolution.width(), vec![[0f32; 3]; resolution.area()]),
            |pixels: &mut (usize, Vec<[f32; 3]>), position, (r, g, b): (f32, f32, f32)| {
                pixels.1[position.y() * pixels.0 + position.x()] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        // One block in flight rather than one per core: decoding's peak
        // memory stays near the map's own size.
        .non_parallel()
        .from_buffered(open()?)
        .map_err(|e| err(format!("cannot decode EXR: {e}")))?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let texels = layer.channel_data.pixels.1;
    if texels.len() != width * height {
        return Err(err("EXR layer size disagrees with its header".into()));
    }
    if let Some(i) = texels
        .iter()
        .position(|t| t.iter().any(|c| !c.is_finite() || *c < 0.0))
    {
        return Err(err(format!(
            "texel ({}, {}) is {:?}; radiance must be finite and ≥ 0",
            i % width,
            i / width,
            texels[i]
        )));
    }
    Ok((width, height, texels))
}

/// Writes `texels` (row-major, top row first) as a half-float RGB EXR, the
/// format the bundled maps use.
pub fn write_exr_half(
    path: &Path,
    width: usize,
    height: usize,
    texels: &[[f32; 3]],
) -> Result<(), exr::error::Error> {
    use exr::prelude::f16;
    exr::prelude::write_rgb_file(path, width, height, |x, y| {
        let t = texels[y * width + x];
        (
            f16::from_f32(t[0]),
            f16::from_f32(t[1]),
            f16::from_f32(t[2]),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(width: usize, height: usize, to_world: DMat3) -> EnvironmentMap {
        let texels = (0..width * height)
            .map(|i| [i as f32, (i % width) as f32, (i / width) as f32])
            .collect();
        EnvironmentMap::new(width, height, texels, 2.0, to_world)
    }

    #[test]
    fn uv_and_direction_are_inverse_and_follow_mitsuba() {
        let m = map(8, 4, DMat3::IDENTITY);
        // Top of the map is +Y; u = 0 looks towards −Z, u = 1/4 towards +X.
        assert!((m.uv_to_direction(0.3, 0.0) - DVec3::Y).length() < 1e-12);
        assert!((m.uv_to_direction(0.0, 0.5) + DVec3::Z).length() < 1e-12);
        assert!((m.uv_to_direction(0.25, 0.5) - DVec3::X).length() < 1e-12);
        for &(u, v) in &[(0.1, 0.2), (0.6, 0.9), (0.99, 0.5)] {
            let (u2, v2) = m.direction_to_uv(m.uv_to_direction(u, v));
            assert!((u - u2).abs() < 1e-12 && (v - v2).abs() < 1e-12);
        }
    }

    #[test]
    fn rotation_turns_the_map() {
        // 90° about +Y carries map −Z (u = 0) to world −X.
        let r = DMat3::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let m = map(8, 4, r);
        let d = m.uv_to_direction(0.0, 0.5);
        assert!((d + DVec3::X).length() < 1e-12, "{d}");
        let (u, v) = m.direction_to_uv(-DVec3::X);
        assert!(u.abs() < 1e-12 || (u - 1.0).abs() < 1e-12);
        assert!((v - 0.5).abs() < 1e-12);
    }

    #[test]
    fn radiance_is_bilinear_between_scaled_texels_as_in_mitsuba() {
        let m = map(8, 4, DMat3::IDENTITY);
        let at = |u: f64, v: f64| m.radiance(m.uv_to_direction(u, v));
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);
        // Texel (3, 2) sits at u = 3.5/8, v = 2/3 (rows run pole to pole).
        assert!(close(
            at(3.5 / 8.0, 2.0 / 3.0),
            [2.0 * 19.0, 2.0 * 3.0, 2.0 * 2.0]
        ));
        // Halfway between columns 3 and 4, and across the seam at u = 0
        // between the last column and the first.
        let mid = |a: [f64; 3], b: [f64; 3]| std::array::from_fn(|k| 0.5 * (a[k] + b[k]));
        assert!(close(at(0.5, 2.0 / 3.0), mid(m.texel(3, 2), m.texel(4, 2))));
        assert!(close(at(0.0, 1.0 / 3.0), mid(m.texel(7, 1), m.texel(0, 1))));
        // A third of the way from row 1 to row 2.
        let v = (1.0 + 1.0 / 3.0) / 3.0;
        let expected: [f64; 3] =
            std::array::from_fn(|k| (2.0 * m.texel(5, 1)[k] + m.texel(5, 2)[k]) / 3.0);
        assert!(close(at(5.5 / 8.0, v), expected));
    }
}
