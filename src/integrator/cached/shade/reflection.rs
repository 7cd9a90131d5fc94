//! How one reflection at a surface point is shaded ([`Reflection`]: its
//! placement options, light samples, record level, what a miss does, which
//! indirect terms it adds), and the delta chains camera paths follow
//! through the cache ([`MAX_DELTA_CHAIN`]).

use super::CachedIntegrator;
use crate::integrator::cached::config::{AMBIENT_MIN_DEPTH, PlacementOptions};
use crate::integrator::cached::shade_point::OnMiss;
use crate::render::PixelSample;

/// How one reflection at a surface point is shaded.
#[derive(Clone, Copy)]
pub(super) struct Reflection<'a> {
    /// Accuracy, occlusion test and path limits of lookups and records.
    pub(super) placement: &'a PlacementOptions,
    pub(super) light_samples: u32,
    /// Level of a record created here (0 at a camera or viewer hit).
    pub(super) level: u32,
    pub(super) on_miss: OnMiss,
    /// The camera ray of a pixel this shading is (see
    /// [`ShadePoint::sample`](crate::integrator::cached::ShadePoint::sample)).
    pub(super) sample: Option<PixelSample>,
    /// Add indirect light (path lengths ≥ 2 from the point).
    pub(super) indirect: bool,
    /// Glossy lobes by BMC; otherwise by one lobe-sampled path.
    pub(super) glossy_bmc: bool,
    /// Dirac-delta bounces (mirrors, glass) a camera path has followed
    /// through the cache to reach this point.
    pub(super) delta_chain: u32,
    /// Cosine-distributed paths that estimate the indirect irradiance
    /// where no record covers the point ([`OnMiss::PathTrace`]).
    pub(super) fallback_paths: u32,
}

/// Longest chain of delta bounces a camera path follows through the cache
/// before it is path traced (two mirrors facing each other would otherwise
/// never end it).
pub(super) const MAX_DELTA_CHAIN: u32 = 8;

impl CachedIntegrator<'_> {
    /// Whether a delta bounce at a point shaded as `r` is followed through
    /// the cache: on camera paths (level 0), for at most
    /// [`MAX_DELTA_CHAIN`] bounces, and where paths may be at least
    /// [`AMBIENT_MIN_DEPTH`] long. The surface the chain reaches is shaded
    /// with the records of the camera's depth, so the chain's bounces are
    /// not counted against `max_depth`: the same approximation as a bounce
    /// through the cache (`shade.rs`'s module docs), negligible where the truncated tail
    /// is.
    pub(super) fn through_delta(&self, r: &Reflection) -> bool {
        r.level == 0
            && r.delta_chain < MAX_DELTA_CHAIN
            && r.placement.paths.max_depth >= AMBIENT_MIN_DEPTH
    }
}
