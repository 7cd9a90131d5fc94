//! Light sources attached to shapes. Environment lighting is separate
//! ([`Environment`](super::Environment)).

use super::error::SceneError;
use super::format::EmitterDoc;

/// Largest accepted radiance component, W/(m²·sr); keeps sums finite.
pub const MAX_RADIANCE: f64 = 1e12;

#[derive(Clone, Debug, PartialEq)]
pub enum Emitter {
    /// Diffuse area light on shape `shape` (index into the scene's shapes),
    /// emitting `radiance` W/(m²·sr) per RGB channel from its front side only
    /// (the side the hit normal points to).
    Area { shape: usize, radiance: [f64; 3] },
}

impl Emitter {
    /// The emitting shape.
    pub fn shape(&self) -> usize {
        match self {
            Emitter::Area { shape, .. } => *shape,
        }
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

impl Emitter {
    pub(crate) fn from_doc(
        doc: &EmitterDoc,
        shape: usize,
        field: &str,
    ) -> Result<Self, SceneError> {
        Ok(Emitter::Area {
            shape,
            radiance: check_radiance(doc.radiance, &format!("{field}.radiance"))?,
        })
    }
}
