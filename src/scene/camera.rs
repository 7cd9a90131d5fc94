//! Perspective camera with Mitsuba 3's conventions: a pinhole
//! (`perspective`) or a thin lens (`thinlens`, depth of field).
//!
//! The camera looks along its local +z with +y up; image x runs towards local
//! −x (Mitsuba's `perspective` sensor), so with `look_at` the image's left is
//! the camera's `up × forward` side. `fov` is the full angle along `fov_axis`:
//! `x`, `y`, `smaller` or `larger` image side.

use glam::{DAffine3, DVec3};

use super::error::SceneError;
use super::format::{CameraDoc, CameraKind, FovAxis};
use super::pixel_filter::PixelFilter;
use super::ray::Ray;
use super::transform;

/// Largest accepted image side, pixels.
pub const MAX_RESOLUTION: u32 = 16384;

#[derive(Clone, Debug)]
pub struct Camera {
    width: u32,
    height: u32,
    /// Camera → world (may carry a uniform scale; directions are normalised).
    to_world: DAffine3,
    /// tan of the half field of view along x and y.
    tan_half: (f64, f64),
    lens: Option<Lens>,
    /// Where in the image a pixel's camera samples fall.
    filter: PixelFilter,
}

/// A thin lens: rays leave a disk of `aperture_radius` in the camera's xy
/// plane and meet where the pinhole ray meets the plane `z =
/// focus_distance` (Mitsuba 3's `thinlens`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Lens {
    aperture_radius: f64,
    focus_distance: f64,
}

/// Mitsuba's default focus distance (its far clip), scene units.
const DEFAULT_FOCUS_DISTANCE: f64 = 1e4;

impl Camera {
    /// A camera at `to_world` with full field of view `fov_degrees` along
    /// `fov_axis`. Callers validate `fov_degrees` ∈ (0, 180) and the size.
    pub fn new(
        to_world: DAffine3,
        fov_degrees: f64,
        fov_axis: FovAxis,
        width: u32,
        height: u32,
    ) -> Self {
        let aspect = width as f64 / height as f64;
        let along_x = match fov_axis {
            FovAxis::X => true,
            FovAxis::Y => false,
            FovAxis::Smaller => aspect <= 1.0,
            FovAxis::Larger => aspect > 1.0,
        };
        let t = (fov_degrees.to_radians() * 0.5).tan();
        let tan_half = if along_x {
            (t, t / aspect)
        } else {
            (t * aspect, t)
        };
        Self {
            width,
            height,
            to_world,
            tan_half,
            lens: None,
            filter: PixelFilter::Box,
        }
    }

    pub(crate) fn from_doc(doc: &CameraDoc, field: &str) -> Result<Self, SceneError> {
        if !(doc.fov > 0.0 && doc.fov < 180.0) {
            return Err(SceneError::invalid(
                format!("{field}.fov"),
                format!("{} is not a field of view in (0, 180) degrees", doc.fov),
            ));
        }
        for (name, value) in [("width", doc.width), ("height", doc.height)] {
            if value == 0 || value > MAX_RESOLUTION {
                return Err(SceneError::invalid(
                    format!("{field}.{name}"),
                    format!("{value} is not in 1..={MAX_RESOLUTION}"),
                ));
            }
        }
        let look = (doc.origin, doc.target, doc.up);
        let to_world = match (&doc.to_world, look) {
            (Some(t), (None, None, None)) => transform::build(t, &format!("{field}.to_world"))?,
            (None, (Some(o), Some(t), Some(u))) => {
                let o = transform::check_vec3(&o, &format!("{field}.origin"))?;
                let t = transform::check_vec3(&t, &format!("{field}.target"))?;
                let u = transform::check_vec3(&u, &format!("{field}.up"))?;
                transform::look_at(o, t, u).ok_or_else(|| {
                    SceneError::invalid(
                        field,
                        "target equals origin or up is parallel to the viewing direction",
                    )
                })?
            }
            _ => {
                return Err(SceneError::invalid(
                    field,
                    "give either `to_world` or all of `origin`, `target` and `up`",
                ));
            }
        };
        let lens_fields = [
            ("aperture_radius", doc.aperture_radius),
            ("focus_distance", doc.focus_distance),
        ];
        let lens = match doc.kind {
            CameraKind::Perspective => {
                if let Some((name, _)) = lens_fields.iter().find(|(_, v)| v.is_some()) {
                    return Err(SceneError::invalid(
                        format!("{field}.{name}"),
                        "only a `thinlens` camera has a lens",
                    ));
                }
                None
            }
            CameraKind::Thinlens => {
                let positive = |name: &str, value: Option<f64>| match value {
                    Some(v) if v > 0.0 && v.is_finite() => Ok(v),
                    Some(v) => Err(SceneError::invalid(
                        format!("{field}.{name}"),
                        format!("{v} is not a positive length"),
                    )),
                    None => Err(SceneError::invalid(
                        field,
                        format!("a thinlens camera needs `{name}`"),
                    )),
                };
                Some(Lens {
                    aperture_radius: positive("aperture_radius", doc.aperture_radius)?,
                    focus_distance: positive(
                        "focus_distance",
                        Some(doc.focus_distance.unwrap_or(DEFAULT_FOCUS_DISTANCE)),
                    )?,
                })
            }
        };
        let filter = match &doc.filter {
            Some(f) => PixelFilter::from_doc(f, &format!("{field}.filter"))?,
            None => PixelFilter::Box,
        };
        Ok(Self {
            lens,
            filter,
            ..Self::new(to_world, doc.fov, doc.fov_axis, doc.width, doc.height)
        })
    }

    /// The image position, in pixels, of a camera sample of pixel
    /// `(px, py)` drawn with `u ∈ [0, 1)²`, as the film's reconstruction
    /// filter distributes them ([`PixelFilter::position`]).
    pub fn pixel_position(&self, px: u32, py: u32, u: [f64; 2]) -> (f64, f64) {
        self.filter.position((px, py), (self.width, self.height), u)
    }

    /// The film's reconstruction filter.
    pub fn filter(&self) -> PixelFilter {
        self.filter
    }

    /// Whether rays leave a lens ([`Self::generate_ray_through_lens`])
    /// rather than a pinhole.
    pub fn has_lens(&self) -> bool {
        self.lens.is_some()
    }

    /// Primary ray through the continuous pixel position (px, py) that
    /// leaves the lens at the point `lens_sample ∈ [0, 1)²` picks
    /// (uniformly by area, Shirley–Chiu); [`Self::generate_ray`] for a pinhole.
    pub fn generate_ray_through_lens(&self, px: f64, py: f64, lens_sample: [f64; 2]) -> Ray {
        let Some(lens) = self.lens else {
            return self.generate_ray(px, py);
        };
        let focus = self.local_direction(px, py) * lens.focus_distance;
        let a = super::shape::concentric_disk(lens_sample) * lens.aperture_radius;
        let aperture = DVec3::new(a.x, a.y, 0.0);
        Ray {
            origin: self.to_world.transform_point3(aperture),
            dir: self
                .to_world
                .transform_vector3(focus - aperture)
                .normalize(),
            t_max: f64::INFINITY,
        }
    }

    /// The pinhole ray's direction through (px, py) in the camera frame,
    /// scaled to `z = 1`.
    fn local_direction(&self, px: f64, py: f64) -> DVec3 {
        let sx = 1.0 - 2.0 * px / self.width as f64;
        let sy = 1.0 - 2.0 * py / self.height as f64;
        DVec3::new(sx * self.tan_half.0, sy * self.tan_half.1, 1.0)
    }

    /// Image size in pixels, (width, height).
    pub fn resolution(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Camera position in world space.
    pub fn origin(&self) -> DVec3 {
        self.to_world.translation
    }

    /// Primary ray through the continuous pixel position (px, py): (0, 0) is
    /// the image's top-left corner, (width, height) its bottom-right corner,
    /// pixel centres are at half-integers. `t_max` is infinite.
    pub fn generate_ray(&self, px: f64, py: f64) -> Ray {
        let local = self.local_direction(px, py);
        Ray {
            origin: self.to_world.translation,
            dir: self.to_world.transform_vector3(local).normalize(),
            t_max: f64::INFINITY,
        }
    }
}

impl Camera {
    /// Where world point `p` appears on the image: the continuous pixel
    /// position (the inverse of [`Self::generate_ray`]) and the distance
    /// along the view axis; `None` behind the camera. The position may lie
    /// outside the image.
    pub fn raster(&self, p: DVec3) -> Option<(f64, f64, f64)> {
        let local = self.to_world.inverse().transform_point3(p);
        if local.z <= 0.0 {
            return None;
        }
        let sx = local.x / local.z / self.tan_half.0;
        let sy = local.y / local.z / self.tan_half.1;
        let px = (1.0 - sx) * self.width as f64 / 2.0;
        let py = (1.0 - sy) * self.height as f64 / 2.0;
        Some((px, py, local.z))
    }

    /// World-space length that one pixel spans at view depth `depth` (along
    /// x, at the image centre).
    pub fn pixel_size_at(&self, depth: f64) -> f64 {
        let scale = self.to_world.matrix3.x_axis.length();
        2.0 * self.tan_half.0 * depth * scale / self.width as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc(extra: serde_json::Value) -> CameraDoc {
        let mut value = serde_json::json!({"fov": 40, "width": 8, "height": 8,
            "origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]});
        value
            .as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        serde_json::from_value(value).unwrap()
    }

    #[test]
    fn a_thin_lens_focuses_its_rays_on_the_focal_plane() {
        let cam = Camera::from_doc(
            &doc(serde_json::json!({"type": "thinlens", "aperture_radius": 0.2, "focus_distance": 3})),
            "camera",
        )
        .unwrap();
        let pinhole = cam.generate_ray(2.5, 6.0);
        let focus = pinhole.origin + pinhole.dir * (3.0 / pinhole.dir.dot(-DVec3::Z));
        for sample in [[0.1, 0.2], [0.9, 0.5], [0.5, 0.99]] {
            let ray = cam.generate_ray_through_lens(2.5, 6.0, sample);
            // Off the pinhole, on the lens disk, through the same focus point.
            let offset = ray.origin - pinhole.origin;
            assert!(
                offset.z.abs() < 1e-12 && offset.length() <= 0.2 + 1e-12 && offset.length() > 0.0
            );
            let t = (focus - ray.origin).dot(ray.dir);
            assert!((ray.origin + ray.dir * t - focus).length() < 1e-9);
        }
        let field = |extra| {
            Camera::from_doc(&doc(extra), "camera")
                .unwrap_err()
                .field()
                .map(str::to_string)
        };
        assert_eq!(
            field(serde_json::json!({"aperture_radius": 0.1})).as_deref(),
            Some("camera.aperture_radius")
        );
        assert_eq!(
            field(serde_json::json!({"type": "thinlens"})).as_deref(),
            Some("camera")
        );
        assert_eq!(
            field(serde_json::json!({"type": "thinlens", "aperture_radius": 0.1, "focus_distance": -1})).as_deref(),
            Some("camera.focus_distance")
        );
    }

    #[test]
    fn raster_inverts_generate_ray() {
        let to_world =
            transform::look_at(DVec3::new(0.3, 0.2, 3.9), DVec3::ZERO, DVec3::Y).unwrap();
        let cam = Camera::new(to_world, 39.3077, FovAxis::Smaller, 200, 100);
        for (px, py) in [(0.5, 0.5), (37.25, 81.0), (199.0, 3.5)] {
            let ray = cam.generate_ray(px, py);
            let (x, y, depth) = cam.raster(ray.origin + 2.5 * ray.dir).expect("in front");
            assert!((x - px).abs() < 1e-9 && (y - py).abs() < 1e-9, "{x} {y}");
            assert!(depth > 0.0);
        }
        assert!(
            cam.raster(cam.origin() - cam.generate_ray(100.0, 50.0).dir)
                .is_none()
        );
    }

    #[test]
    fn cornell_camera_sees_red_on_the_left() {
        let to_world =
            transform::look_at(DVec3::new(0.0, 0.0, 3.9), DVec3::ZERO, DVec3::Y).unwrap();
        let cam = Camera::new(to_world, 39.3077, FovAxis::Smaller, 256, 256);
        let centre = cam.generate_ray(128.0, 128.0);
        assert!((centre.dir + DVec3::Z).length() < 1e-12);
        // Left edge looks towards −x (Mitsuba's red wall), top edge towards +y.
        let left = cam.generate_ray(0.0, 128.0);
        assert!(left.dir.x < 0.0 && left.dir.y.abs() < 1e-12);
        let top = cam.generate_ray(128.0, 0.0);
        assert!(top.dir.y > 0.0);
        let half = (39.3077f64.to_radians() / 2.0).tan();
        assert!((left.dir.x / left.dir.z - half).abs() < 1e-12);
    }

    #[test]
    fn fov_axis_picks_the_side() {
        let cam = Camera::new(DAffine3::IDENTITY, 90.0, FovAxis::Smaller, 200, 100);
        // Smaller side is y: its half-angle is 45°, x gets twice the tangent.
        let top = cam.generate_ray(100.0, 0.0);
        assert!((top.dir.y / top.dir.z - 1.0).abs() < 1e-12);
        let right = cam.generate_ray(200.0, 50.0);
        assert!((right.dir.x / right.dir.z + 2.0).abs() < 1e-12);
    }
}
