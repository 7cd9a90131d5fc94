//! `area`: a diffuse area light on a shape (Mitsuba 3's `area` emitter,
//! nested in the `<shape>` it lights; a JSON shape's `emitter`), emitting
//! from its front side only (the side the hit normal points to).
//!
//! Parameters: `radiance` (W/(m²·sr) per channel, a colour in
//! `[0, MAX_RADIANCE]` or a texture over the shape's texture coordinates,
//! Mitsuba's textured `area`; default 1).
//!
//! Sampling draws a point uniformly by area with
//! `Scene::sample_shape_area_uv` and converts its density to solid angle at
//! the shading point, `p_ω = p_A d² / |cos θ_l|` (pbrt-v4 §12.2.3); its
//! reach is `A lum(L̄)` over the squared distance to its bounding sphere.

use glam::DVec3;
use serde_json::Map;

use super::{Light, LightSample, Reach, check_radiance, power};
use crate::color::Rgb;
use crate::scene::Scene;
use crate::scene::bitmap::Bitmaps;
use crate::scene::error::SceneError;
use crate::scene::format::EmitterDoc;
use crate::scene::params::Params;
use crate::scene::texture::Texture;

/// An area light; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct AreaLight {
    /// The emitting shape, an index into the scene's shapes.
    pub shape: usize,
    /// Emitted radiance, W/(m²·sr) per RGB channel.
    pub radiance: Texture,
}

impl AreaLight {
    /// The area light `doc` of shape `shape`; `field` names it in errors,
    /// a texture's images are read through `bitmaps`.
    pub(crate) fn parse(
        doc: &EmitterDoc,
        shape: usize,
        field: &str,
        bitmaps: &Bitmaps,
    ) -> Result<Self, SceneError> {
        let mut map = Map::new();
        map.insert("radiance".into(), doc.radiance.clone());
        let mut params = Params::new(field, map).with_bitmaps(bitmaps);
        let radiance = if doc.radiance.is_object() {
            let value = params.take("radiance").expect("present");
            let texture = Texture::parse(&params, "radiance", value)?;
            check_radiance([texture.max(); 3], &params.field("radiance"))?;
            texture
        } else {
            Texture::Constant(power(&mut params, "radiance", 1.0)?)
        };
        Ok(Self { shape, radiance })
    }
}

impl Light for AreaLight {
    fn reach(&self, scene: &Scene) -> Reach {
        let (lo, hi) = scene.shape_bounds(self.shape);
        Reach::Surface {
            strength: scene.shape_area(self.shape)
                * Rgb::from_array(self.radiance.mean()).luminance(),
            center: 0.5 * (lo + hi),
            radius2: (0.5 * (hi - lo)).length_squared(),
        }
    }

    fn sample(&self, scene: &Scene, x: DVec3, p_select: f64, u: [f64; 2]) -> Option<LightSample> {
        let (point, normal, pdf_area, uv) = scene.sample_shape_area_uv(self.shape, u);
        let d = point - x;
        let dist2 = d.length_squared();
        if dist2 <= 0.0 || pdf_area <= 0.0 {
            return None;
        }
        let wi = d / dist2.sqrt();
        let cos_light = -normal.dot(wi);
        if cos_light <= 0.0 {
            return None;
        }
        Some(LightSample {
            wi,
            radiance: Rgb::from_array(self.radiance.eval(uv)),
            pdf: p_select * pdf_area * dist2 / cos_light,
            target: Some((point, Some(normal))),
            delta: false,
        })
    }
}
