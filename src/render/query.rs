//! Query points: where and facing which way irradiance is wanted.

use std::f64::consts::TAU;

use glam::DVec3;
use rand::{Rng, RngExt};

use super::error::RenderError;
use crate::sphere::Frame;

/// A query point as a request or a points file writes it: world position
/// and the normal of the hemisphere of interest.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PointDoc {
    pub position: [f64; 3],
    /// Need not be unit length; must be finite and non-zero.
    pub normal: [f64; 3],
}

impl PointDoc {
    /// The checked point (normal normalised); errors name the bad field.
    pub fn point(&self) -> Result<QueryPoint, RenderError> {
        QueryPoint::new(DVec3::from(self.position), DVec3::from(self.normal))
    }
}

/// A position with a unit normal; the hemisphere of interest is the side the
/// normal points to.
///
/// Invariant: every coordinate is finite and `normal` has unit length, so
/// downstream code never sees NaN or a degenerate frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryPoint {
    position: DVec3,
    normal: DVec3,
}

/// Largest accepted coordinate of a query position, in world units. Far
/// beyond any scene, and small enough that rays from there keep the
/// precision to hit one: at 1e308 the intersection arithmetic overflowed
/// and every point read zero instead of being refused.
pub const MAX_COORDINATE: f64 = 1e9;

impl QueryPoint {
    /// Validates and normalises `normal`. Errors name the bad field.
    pub fn new(position: DVec3, normal: DVec3) -> Result<Self, RenderError> {
        if !position.is_finite() || position.abs().max_element() > MAX_COORDINATE {
            return Err(RenderError::InvalidPoint {
                field: "position",
                reason: format!(
                    "must be finite with coordinates within ±{MAX_COORDINATE:e}, got {position}"
                ),
            });
        }
        if !normal.is_finite() {
            return Err(RenderError::InvalidPoint {
                field: "normal",
                reason: format!("must be finite, got {normal}"),
            });
        }
        let length = normal.length();
        if length.is_nan() || length <= 1e-12 || !length.is_finite() {
            return Err(RenderError::InvalidPoint {
                field: "normal",
                reason: format!("must have non-zero length, got {normal}"),
            });
        }
        Ok(Self {
            position,
            normal: normal / length,
        })
    }

    /// World-space position.
    pub fn position(&self) -> DVec3 {
        self.position
    }

    /// Unit world-space normal.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// The point's local frame (z = the normal) turned about the normal by
    /// a uniform angle, one number drawn from `rng`: a hemisphere rule's
    /// directions in it are a randomised rule, so its estimates are
    /// unbiased.
    pub fn turned_frame<R: Rng + ?Sized>(&self, rng: &mut R) -> Frame {
        Frame::from_normal(self.normal).rotated_about_normal(TAU * rng.random::<f64>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_is_normalised() {
        let q = QueryPoint::new(DVec3::ONE, DVec3::new(0.0, 3.0, 4.0)).unwrap();
        assert!((q.normal() - DVec3::new(0.0, 0.6, 0.8)).length() < 1e-15);
    }

    #[test]
    fn bad_inputs_name_the_field() {
        let err = QueryPoint::new(DVec3::ONE, DVec3::ZERO).unwrap_err();
        assert!(matches!(
            err,
            RenderError::InvalidPoint {
                field: "normal",
                ..
            }
        ));
        let err = QueryPoint::new(DVec3::new(f64::NAN, 0.0, 0.0), DVec3::Z).unwrap_err();
        assert!(matches!(
            err,
            RenderError::InvalidPoint {
                field: "position",
                ..
            }
        ));
        let err = QueryPoint::new(DVec3::ZERO, DVec3::new(0.0, f64::INFINITY, 0.0)).unwrap_err();
        assert!(matches!(
            err,
            RenderError::InvalidPoint {
                field: "normal",
                ..
            }
        ));
    }
}
