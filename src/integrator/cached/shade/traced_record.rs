//! A record gathered in two steps ([`trace_record`], then
//! [`TracedRecord::continue_paths`]): first segments alone, which give its
//! radius, then the paths that continue from them; the same bits as
//! `gather_record` in one step.

use rand_pcg::Pcg64;

use super::RecordGather;
use crate::cache::RecordRule;
use crate::integrator::cached::record_estimate::{GatheredRecord, PlacementPoint};
use crate::integrator::cached::stats::ShadingStats;
use crate::render::{FirstSegment, RenderError, TraceStats, Transport};
use crate::sphere::Frame;

/// A record's first segments only ([`trace_record`]): enough for its
/// radius, which depends on the distances alone.
pub struct TracedRecord {
    frame: Frame,
    segments: Vec<FirstSegment>,
    /// The record's generator, as the first segments left it (they draw
    /// nothing), for the paths that continue from them.
    rng: Pcg64,
}

impl TracedRecord {
    /// Distance to the first hit along each direction (∞ where none).
    pub fn distances(&self) -> Vec<f64> {
        self.segments.iter().map(FirstSegment::distance).collect()
    }

    /// The record's radiance samples from its first segments, gathered as
    /// `how` says (the `how` it was traced with): the same bits as
    /// [`gather_record`](super::gather_record) with the same generator. Rays are counted in
    /// `stats`.
    pub fn continue_paths(
        mut self,
        transport: &Transport,
        how: &RecordGather,
        stats: &mut ShadingStats,
    ) -> Result<GatheredRecord, RenderError> {
        let samples = how.continue_segments(transport, &self.segments, &mut self.rng, stats)?;
        Ok(GatheredRecord {
            frame: self.frame,
            samples,
        })
    }
}

/// The first step of [`gather_record`](super::gather_record) by paths or through the secondary
/// cache: the frame turned by a random angle from `rng`, then each
/// direction's first segment; the rest waits for
/// [`TracedRecord::continue_paths`]. Rays are counted in `stats`.
pub fn trace_record(
    transport: &Transport,
    rule: &RecordRule,
    target: &PlacementPoint,
    how: &RecordGather,
    mut rng: Pcg64,
    stats: &mut ShadingStats,
) -> TracedRecord {
    let point = &target.point;
    let frame = point.turned_frame(&mut rng);
    let mut trace = TraceStats::default();
    let segments = transport.hemisphere_first_segments(
        point,
        &frame,
        rule.directions(),
        how.paths,
        &mut trace,
    );
    stats.rays += trace.rays;
    TracedRecord {
        frame,
        segments,
        rng,
    }
}
