//! Irradiance-cache records as the camera sees them (like Radiance's
//! `lookamb`, but on the image): where each record sits on the image and how
//! far its validity radius reaches there, as data and as a transparent
//! overlay to lay over a tile.

use serde::Serialize;

use crate::cache::Record;
use crate::scene::Camera;

/// One record seen from the camera.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordView {
    /// World position, unit normal, validity radius (world units) and
    /// irradiance (W/m², RGB) of the record.
    pub position: [f64; 3],
    pub normal: [f64; 3],
    pub radius: f64,
    pub irradiance: [f64; 3],
    /// Continuous pixel position of the record on the camera image
    /// (pixel centres at half-integers).
    pub pixel: [f64; 2],
    /// The validity radius in pixels at the record's depth (the radius
    /// seen face-on; a slanted surface shows it shorter across).
    pub radius_pixels: f64,
}

/// The records in front of the camera.
pub fn record_views(camera: &Camera, records: &[Record]) -> Vec<RecordView> {
    records
        .iter()
        .filter_map(|r| {
            let (px, py, depth) = camera.raster(r.position)?;
            Some(RecordView {
                position: r.position.to_array(),
                normal: r.normal.to_array(),
                radius: r.radius,
                irradiance: r.irradiance.to_array(),
                pixel: [px, py],
                radius_pixels: r.radius / camera.pixel_size_at(depth),
            })
        })
        .collect()
}

/// Colours of the overlay (straight RGBA): validity circles, record centres.
const CIRCLE: [u8; 4] = [64, 224, 255, 96];
const CENTRE: [u8; 4] = [255, 64, 160, 255];

/// An RGBA overlay of `width × height` pixels whose top-left pixel is image
/// pixel `(x, y)`: transparent, with each record's validity circle outlined
/// and its centre marked. Returns row-major RGBA bytes.
pub fn record_overlay(views: &[RecordView], x: u32, y: u32, width: u32, height: u32) -> Vec<u8> {
    let (w, h) = (width as usize, height as usize);
    let mut rgba = vec![0u8; w * h * 4];
    let mut put = |px: f64, py: f64, colour: [u8; 4]| {
        let (cx, cy) = ((px - f64::from(x)).floor(), (py - f64::from(y)).floor());
        if cx >= 0.0 && cy >= 0.0 && (cx as usize) < w && (cy as usize) < h {
            let i = (cy as usize * w + cx as usize) * 4;
            rgba[i..i + 4].copy_from_slice(&colour);
        }
    };
    for v in views {
        let [px, py] = v.pixel;
        // The outline, one point per pixel of circumference (at least 8).
        let r = v
            .radius_pixels
            .clamp(1.5, 4.0 * f64::from(width.max(height)));
        let steps = (std::f64::consts::TAU * r).ceil().max(8.0) as usize;
        for k in 0..steps {
            let phi = std::f64::consts::TAU * k as f64 / steps as f64;
            put(px + r * phi.cos(), py + r * phi.sin(), CIRCLE);
        }
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
            put(px + dx, py + dy, CENTRE);
        }
    }
    rgba
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_land_where_the_camera_sees_them() {
        let transport = crate::testing::cornell(32);
        let camera = &transport.scene().camera;
        let ray = camera.generate_ray(10.5, 20.5);
        let hit = transport
            .scene()
            .intersect(&ray)
            .expect("the box is closed");
        let record = Record {
            position: hit.position,
            normal: hit.shading_normal,
            irradiance: crate::render::Rgb::new(1.0, 2.0, 3.0),
            variance: crate::render::Rgb::BLACK,
            radius: 0.1,
            rotation_gradient: [glam::DVec3::ZERO; 3],
            translation_gradient: [glam::DVec3::ZERO; 3],
        };
        let views = record_views(camera, &[record]);
        assert_eq!(views.len(), 1);
        let [px, py] = views[0].pixel;
        assert!((px - 10.5).abs() < 1e-6 && (py - 20.5).abs() < 1e-6);
        assert!(views[0].radius_pixels > 0.0);
        let overlay = record_overlay(&views, 0, 16, 16, 16);
        let at = |x: usize, y: usize| &overlay[(y * 16 + x) * 4..(y * 16 + x) * 4 + 4];
        assert_eq!(at(10, 4), CENTRE);
        // Far from the record: transparent.
        assert_eq!(at(0, 15)[3], 0);
    }
}
