//! How a shading point is shaded through the cache: what a miss does
//! ([`OnMiss`]), the camera ray or view direction that reaches it
//! ([`ShadePoint`]) and an ambient bounce of a record's rays ([`Bounce`]).

use crate::render::{PathDepth, PathLimits, PixelSample};

/// What to do where no record covers a shading point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnMiss {
    /// Compute a record there and insert it (Ward's lazy evaluation).
    Insert,
    /// Leave the cache alone: retry at accuracy 1, else estimate the
    /// indirect irradiance by one cosine-sampled path (a read-only pass).
    PathTrace,
}

/// How a point seen along a camera ray or a query direction is shaded.
#[derive(Clone, Copy, Debug)]
pub struct ShadePoint {
    /// The depth of the camera ray or view direction that reaches the
    /// point, counted from the camera or viewer (the segment arriving here
    /// is the first): 1 = the point's emission only, 2 = plus direct light,
    /// ≥ 3 adds indirect light. The cache's records must have been made for
    /// the same depth (`CachedConfig::records_key`).
    pub max_depth: PathDepth,
    pub on_miss: OnMiss,
    /// The camera ray of a pixel this point is, if it is one: its light
    /// samples then take their share of one pattern over the pixel's rays.
    pub sample: Option<PixelSample>,
    /// The point is in a tile without records (`dense`): its direct light
    /// takes `DENSE_LIGHT_FACTOR` times the configuration's light samples,
    /// its indirect light `DENSE_INDIRECT_PATHS` paths.
    pub dense: bool,
}

/// An ambient bounce of a record's rays through the cache (module docs).
#[derive(Clone, Copy, Debug)]
pub struct Bounce {
    /// The paths the record's rays sum.
    pub paths: PathLimits,
    /// Level of the record being computed (0 = placed for a shading point).
    pub level: u32,
    pub on_miss: OnMiss,
}
