//! The denoiser's guides for a rectangle of the camera image
//! ([`crate::image::denoise`]): what the camera's first hits are in each
//! pixel — shading normal, position, the pixel's footprint there and the
//! diffuse albedo seen from the camera — from four rays on a 2×2 grid
//! over the pixel. A pixel whose four rays do not all see one smooth
//! surface (an edge, a silhouette, the background, an emitter) gets its
//! albedo but no normal: its value mixes surfaces, so the filter weighs
//! its neighbours by value alone and lends it to no pixel that has a
//! normal. No random numbers, so a tile's guides are the same on every
//! request.

use glam::DVec3;
use rayon::prelude::*;

use super::transport::Transport;
use crate::image::{GuideBuffers, GuidePixel};

/// Sub-pixel positions of a pixel's guide rays.
const GRID: [(f64, f64); 4] = [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)];
/// Largest angle between the rays' normals within one surface: cos 18°.
const SAME_NORMAL: f64 = 0.95;
/// Largest distance of a ray's hit off the first one's tangent plane within
/// one surface, in pixel footprints.
const SAME_PLANE: f64 = 0.5;

/// What one guide ray found: a surface's normal, hit, footprint and albedo.
type Seen = (DVec3, DVec3, f64, [f64; 3]);

impl Transport {
    /// Guides of the `width × height` pixels whose top-left one is (x, y),
    /// row-major, and the camera rays traced for them (four per pixel).
    pub fn guide_buffers(&self, x: u32, y: u32, width: u32, height: u32) -> (GuideBuffers, u64) {
        let pixels = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (px, py) = (f64::from(x + i % width), f64::from(y + i / width));
                let seen = GRID.map(|(dx, dy)| self.first_surface(px + dx, py + dy));
                guide_of(&seen)
            })
            .collect();
        let buffers = GuideBuffers {
            width,
            height,
            pixels,
        };
        (
            buffers,
            u64::from(width) * u64::from(height) * GRID.len() as u64,
        )
    }

    /// The surface the camera ray through raster position (px, py) hits
    /// first, or `None` for the background or an emitter (exact values).
    fn first_surface(&self, px: f64, py: f64) -> Option<Seen> {
        let scene = self.scene();
        let camera = &scene.camera;
        let ray = camera.generate_ray(px, py);
        let hit = scene.intersect(&ray)?;
        if hit.emitter.is_some() {
            return None;
        }
        let bsdf = self.bsdf_at(&hit)?;
        let wo = bsdf.frame_at(&hit).to_local(-ray.dir);
        let depth = (hit.position - ray.origin).length();
        Some((
            hit.shading_normal,
            hit.position,
            camera.pixel_size_at(depth),
            bsdf.lambertian(wo).to_array(),
        ))
    }
}

/// A pixel's guide from its rays: the albedo is their mean (zero where a
/// ray found no surface), the rest their mean if they all saw one smooth
/// surface, else no normal.
fn guide_of(seen: &[Option<Seen>]) -> GuidePixel {
    let count = seen.len() as f64;
    let albedo = seen
        .iter()
        .flatten()
        .map(|s| DVec3::from_array(s.3))
        .sum::<DVec3>()
        / count;
    let mut guide = GuidePixel {
        normal: None,
        mean_normal: seen.iter().flatten().map(|s| s.0).sum::<DVec3>() / count,
        position: DVec3::ZERO,
        footprint: 0.0,
        albedo: albedo.to_array(),
    };
    let surfaces: Vec<Seen> = seen.iter().flatten().copied().collect();
    let Some(&(n0, x0, footprint, _)) = surfaces.first() else {
        return guide;
    };
    let smooth = surfaces.len() == seen.len()
        && surfaces.iter().all(|&(n, x, _, _)| {
            n.dot(n0) >= SAME_NORMAL && n0.dot(x - x0).abs() <= SAME_PLANE * footprint
        });
    if smooth {
        guide.normal = Some((surfaces.iter().map(|s| s.0).sum::<DVec3>() / count).normalize());
        guide.position = surfaces.iter().map(|s| s.1).sum::<DVec3>() / count;
        guide.footprint = surfaces.iter().map(|s| s.2).sum::<f64>() / count;
    }
    guide
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::testing::cornell;

    #[test]
    fn a_pixel_has_a_guide_only_on_one_smooth_surface() {
        let at = |n: DVec3, x: DVec3| Some((n, x, 0.01, [0.5; 3]));
        let flat: Vec<Option<Seen>> = (0..4)
            .map(|k| at(DVec3::Z, DVec3::new(f64::from(k) * 0.005, 0.0, 0.0)))
            .collect();
        let guide = guide_of(&flat);
        assert_eq!(guide.normal, Some(DVec3::Z));
        assert!((guide.position.x - 0.0075).abs() < 1e-12);
        assert_eq!(guide.albedo, [0.5; 3]);
        // A crease between two walls.
        let mut crease = flat.clone();
        crease[3] = at(DVec3::X, DVec3::ZERO);
        assert_eq!(guide_of(&crease).normal, None);
        // A box's face in front of the wall behind it: same normal, a step in depth.
        let mut step = flat.clone();
        step[2] = at(DVec3::Z, DVec3::new(0.0, 0.0, 0.2));
        assert_eq!(guide_of(&step).normal, None);
        // The background or an emitter in one ray: the albedo is the rays' mean.
        let mut silhouette = flat.clone();
        silhouette[0] = None;
        let guide = guide_of(&silhouette);
        assert_eq!((guide.normal, guide.albedo), (None, [0.375; 3]));
    }

    #[test]
    fn the_cornell_box_floor_faces_up_and_its_light_is_left_alone() {
        let transport = cornell(32);
        let (guides, rays) = transport.guide_buffers(0, 0, 32, 32);
        assert_eq!(rays, 4 * 32 * 32);
        // The lower half sees the white floor and the short box's top, both
        // facing +y, with the white's albedo (0.886, 0.699, 0.666).
        let floor: Vec<_> = guides.pixels[16 * 32..]
            .iter()
            .filter(|g| g.normal.is_some_and(|n| n.dot(DVec3::Y) > 0.99))
            .collect();
        assert!(floor.len() > 50, "{} floor pixels", floor.len());
        for g in floor {
            assert!((g.albedo[0] - 0.886).abs() < 1e-3, "{g:?}");
            assert!(g.position.y < -0.39 && g.footprint > 0.0, "{g:?}");
        }
        // The left wall is red.
        let left = guides.pixels[16 * 32 + 1];
        assert!(left.normal.unwrap().dot(DVec3::X) > 0.99 && left.albedo[0] > 5.0 * left.albedo[1]);
        // Some pixel of the top centre sees the area light: no guide.
        let mut top_centre = (0..8).flat_map(|row| (8..24).map(move |column| row * 32 + column));
        let light = top_centre.any(|i| guides.pixels[i].normal.is_none());
        assert!(light, "no pixel of the ceiling's light was left alone");
    }
}
