//! What tracing cost: the counters a caller sums over a request.

/// Counters a caller sums over a request.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceStats {
    /// Closest-hit plus shadow rays traced.
    pub rays: u64,
}
