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
    /// Half the image's extent along x and y at unit distance: tan of the
    /// half field of view (perspective), or in camera units on the image
    /// plane itself (orthographic).
    tan_half: (f64, f64),
    /// Rays leave a plane, not a point: Mitsuba's `orthographic`.
    orthographic: bool,
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
            orthographic: false,
            lens: None,
            filter: PixelFilter::Box,
        }
    }

    /// An orthographic camera at `to_world`: parallel rays along its +z
    /// from the rectangle x ∈ [−1, 1], y ∈ [−1/aspect, 1/aspect] of its xy
    /// plane (Mitsuba 3's `orthographic`, rays from its near plane at 0).
    pub fn orthographic(to_world: DAffine3, width: u32, height: u32) -> Self {
        let aspect = width as f64 / height as f64;
        Self {
            tan_half: (1.0, 1.0 / aspect),
            orthographic: true,
            // The field of view is unused.
            ..Self::new(to_world, 90.0, FovAxis::X, width, height)
        }
    }

    pub(crate) fn from_doc(doc: &CameraDoc, field: &str) -> Result<Self, SceneError> {
        let fov = match (doc.kind, doc.fov) {
            (CameraKind::Orthographic, None) => None,
            (CameraKind::Orthographic, Some(_)) => {
                return Err(SceneError::invalid(
                    format!("{field}.fov"),
                    "an orthographic camera has no field of view; `to_world`'s scale sizes its image",
                ));
            }
            (_, None) => {
                return Err(SceneError::invalid(
                    field,
                    "a perspective or thinlens camera needs `fov`",
                ));
            }
            (_, Some(fov)) if fov > 0.0 && fov < 180.0 => Some(fov),
            (_, Some(fov)) => {
                return Err(SceneError::invalid(
                    format!("{field}.fov"),
                    format!("{fov} is not a field of view in (0, 180) degrees"),
                ));
            }
        };
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
            CameraKind::Perspective | CameraKind::Orthographic => {
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
        let camera = match fov {
            Some(fov) => Self::new(to_world, fov, doc.fov_axis, doc.width, doc.height),
            None => Self::orthographic(to_world, doc.width, doc.height),
        };
        Ok(Self {
            lens,
            filter,
            ..camera
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
        let focus = self.image_plane(px, py) * lens.focus_distance;
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

    /// The point of the image plane `z = 1` (perspective) or `z = 0`
    /// (orthographic) that (px, py) maps to, in the camera frame: the
    /// pinhole ray's direction scaled to `z = 1`, or the orthographic ray's
    /// origin.
    fn image_plane(&self, px: f64, py: f64) -> DVec3 {
        let sx = 1.0 - 2.0 * px / self.width as f64;
        let sy = 1.0 - 2.0 * py / self.height as f64;
        let z = if self.orthographic { 0.0 } else { 1.0 };
        DVec3::new(sx * self.tan_half.0, sy * self.tan_half.1, z)
    }

    /// Image size in pixels, (width, height).
    pub fn resolution(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Primary ray through the continuous pixel position (px, py): (0, 0) is
    /// the image's top-left corner, (width, height) its bottom-right corner,
    /// pixel centres are at half-integers. `t_max` is infinite.
    pub fn generate_ray(&self, px: f64, py: f64) -> Ray {
        let local = self.image_plane(px, py);
        let (origin, dir) = match self.orthographic {
            true => (self.to_world.transform_point3(local), DVec3::Z),
            false => (self.to_world.translation, local),
        };
        Ray {
            origin,
            dir: self.to_world.transform_vector3(dir).normalize(),
            t_max: f64::INFINITY,
        }
    }

    /// World length that `pixels` pixels span across the image at
    /// distance `t` along the ray through (px, py): the angle between that
    /// ray and the one `pixels` to its right times `t` (perspective), the
    /// fixed spacing of parallel rays (orthographic).
    pub fn span_at(&self, px: f64, py: f64, pixels: f64, t: f64) -> f64 {
        let (a, b) = (
            self.generate_ray(px, py),
            self.generate_ray(px + pixels, py),
        );
        match self.orthographic {
            true => (a.origin - b.origin).length(),
            false => t * a.dir.angle_between(b.dir),
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
        let z = if self.orthographic { 1.0 } else { local.z };
        let sx = local.x / z / self.tan_half.0;
        let sy = local.y / z / self.tan_half.1;
        let px = (1.0 - sx) * self.width as f64 / 2.0;
        let py = (1.0 - sy) * self.height as f64 / 2.0;
        Some((px, py, local.z))
    }

    /// World-space length that one pixel spans at view depth `depth` (along
    /// x, at the image centre).
    pub fn pixel_size_at(&self, depth: f64) -> f64 {
        let scale = self.to_world.matrix3.x_axis.length();
        let depth = if self.orthographic { 1.0 } else { depth };
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

    /// The field the error of a camera document with `extra` names.
    fn field(extra: serde_json::Value) -> Option<String> {
        Camera::from_doc(&doc(extra), "camera")
            .unwrap_err()
            .field()
            .map(str::to_string)
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
    fn an_orthographic_camera_sends_parallel_rays_from_its_scaled_plane() {
        let cam = Camera::from_doc(
            &doc(serde_json::json!({"type": "orthographic", "fov": null,
                "origin": null, "target": null, "up": null, "width": 8, "height": 4,
                "to_world": [{"scale": [3, 3, 1]}, {"translate": [0, 0, 5]}]})),
            "camera",
        )
        .unwrap();
        // The image spans x ∈ [−3, 3], y ∈ [−1.5, 1.5]; +x of the camera is
        // the image's left, as for the perspective camera.
        let corner = cam.generate_ray(0.0, 0.0);
        assert!((corner.origin - DVec3::new(3.0, 1.5, 5.0)).length() < 1e-12);
        let centre = cam.generate_ray(4.0, 2.0);
        assert!((centre.origin - DVec3::new(0.0, 0.0, 5.0)).length() < 1e-12);
        assert_eq!((corner.dir, centre.dir), (DVec3::Z, DVec3::Z));
        assert!((cam.span_at(1.5, 2.5, 1.0, 100.0) - 0.75).abs() < 1e-12);
        assert!((cam.pixel_size_at(100.0) - 0.75).abs() < 1e-12);
        for (px, py) in [(0.5, 0.5), (7.25, 3.0)] {
            let ray = cam.generate_ray(px, py);
            let (x, y, depth) = cam.raster(ray.origin + 2.5 * ray.dir).unwrap();
            assert!((x - px).abs() < 1e-9 && (y - py).abs() < 1e-9);
            assert!((depth - 2.5).abs() < 1e-12);
        }
        assert_eq!(
            field(serde_json::json!({"type": "orthographic"})).as_deref(),
            Some("camera.fov")
        );
        assert_eq!(
            field(serde_json::json!({"fov": null})).as_deref(),
            Some("camera")
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
            cam.raster(to_world.translation - cam.generate_ray(100.0, 50.0).dir)
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
