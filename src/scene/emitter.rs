//! Light sources: area lights attached to shapes, and the delta lights a
//! scene lists under `lights` (Mitsuba 3's `point`, `spot` and
//! `directional`). Environment lighting is separate
//! ([`Environment`](super::Environment)).
//!
//! A light document is `{"type": PLUGIN, PARAMETER: value, …}` with
//! Mitsuba's plugin and parameter names; each plugin parses its own
//! parameters in its own file below, and [`LIGHTS`] is the registry.

mod directional;
mod point;
mod spot;

use serde_json::{Map, Value};

use super::bitmap::Bitmaps;
use super::error::SceneError;
use super::format::EmitterDoc;
use super::params::Params;
use super::texture::Texture;

/// Largest accepted radiance component, W/(m²·sr); keeps sums finite.
pub const MAX_RADIANCE: f64 = 1e12;

#[derive(Clone, Debug, PartialEq)]
pub enum Emitter {
    /// Diffuse area light on shape `shape` (index into the scene's shapes),
    /// emitting `radiance` W/(m²·sr) per RGB channel from its front side only
    /// (the side the hit normal points to), constant or a texture over the
    /// shape's texture coordinates (Mitsuba's textured `area` emitter).
    Area { shape: usize, radiance: Texture },
    /// An isotropic point light at `position` of radiant intensity
    /// `intensity` (W/sr per channel): irradiance `I cos θ / d²` at distance `d`.
    Point {
        position: [f64; 3],
        intensity: [f64; 3],
    },
    /// A spot light at `position` shining along the unit `direction`: its
    /// intensity is `intensity` (W/sr) within `beam_width` of the axis and
    /// falls linearly in angle to zero at `cutoff_angle` (radians,
    /// `0 < beam_width ≤ cutoff_angle < π`), as Mitsuba 3's.
    Spot {
        position: [f64; 3],
        direction: [f64; 3],
        intensity: [f64; 3],
        cutoff_angle: f64,
        beam_width: f64,
    },
    /// Light from infinitely far away travelling along the unit `direction`,
    /// `irradiance` W/m² on a surface facing it.
    Directional {
        direction: [f64; 3],
        irradiance: [f64; 3],
    },
}

impl Emitter {
    /// The emitting shape of an area light.
    pub fn shape(&self) -> Option<usize> {
        match self {
            Emitter::Area { shape, .. } => Some(*shape),
            _ => None,
        }
    }

    /// Whether the light is a Dirac delta in position or direction: no ray
    /// can hit it, only light samples reach it.
    pub fn is_delta(&self) -> bool {
        !matches!(self, Emitter::Area { .. })
    }
}

/// Validates an RGB radiance: finite, non-negative, ≤ [`MAX_RADIANCE`].
pub(crate) fn check_radiance(value: [f64; 3], field: &str) -> Result<[f64; 3], SceneError> {
    for (i, x) in value.iter().enumerate() {
        if !(0.0..=MAX_RADIANCE).contains(x) {
            return Err(SceneError::invalid(
                format!("{field}[{i}]"),
                format!("{x} is not a radiance in [0, {MAX_RADIANCE:e}]"),
            ));
        }
    }
    Ok(value)
}

/// A light plugin's parser: its parameters to an emitter.
type Parse = fn(&mut Params) -> Result<Emitter, SceneError>;

/// Every light plugin of a scene's `lights`, by its `type`.
const LIGHTS: &[(&str, Parse)] = &[
    ("point", point::parse),
    ("spot", spot::parse),
    ("directional", directional::parse),
];

/// The light plugin names a scene's `lights` accept, for messages and docs.
pub fn light_names() -> Vec<&'static str> {
    LIGHTS.iter().map(|(name, _)| *name).collect()
}

/// An emitted quantity (`intensity`, `irradiance`): a colour in
/// `[0, MAX_RADIANCE]`, `default` when absent.
fn power(params: &mut Params, name: &str, default: f64) -> Result<[f64; 3], SceneError> {
    let value = params.color(name)?.unwrap_or([default; 3]);
    check_radiance(value, &params.field(name))
}

impl Emitter {
    /// The area light `doc` of shape `shape`; `field` names it in errors,
    /// a texture's images are read through `bitmaps`.
    pub(crate) fn from_doc(
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
        Ok(Emitter::Area { shape, radiance })
    }

    /// Validates one `lights[i]` entry (`field` its path): `type` names a
    /// plugin of [`LIGHTS`], the rest are its parameters.
    pub(crate) fn from_light_doc(
        doc: &Map<String, Value>,
        field: &str,
    ) -> Result<Self, SceneError> {
        let mut map = doc.clone();
        let kind = match map.remove("type") {
            Some(Value::String(kind)) => kind,
            _ => return Err(SceneError::invalid(field, "missing field `type`")),
        };
        let Some((_, parse)) = LIGHTS.iter().find(|(name, _)| *name == kind) else {
            let known: Vec<&str> = LIGHTS.iter().map(|(name, _)| *name).collect();
            return Err(SceneError::invalid(
                format!("{field}.type"),
                format!("unknown light type {kind:?} (known: {})", known.join(", ")),
            ));
        };
        let mut params = Params::new(field, map);
        let emitter = parse(&mut params)?;
        params.finish()?;
        Ok(emitter)
    }
}
