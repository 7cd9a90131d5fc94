//! Rays a request spends on work it keeps for later requests: kernel fits,
//! calibrations and their training references, the records priors' twins.
//! Such work is done once per scene and configuration (whichever request
//! needs it first), so a response counts it in its `rays` and says how much
//! of them it was.

use std::sync::atomic::{AtomicU64, Ordering};

/// A request's count of rays spent on shared, kept work (module docs).
/// Added to from the threads of the request's computations.
#[derive(Debug, Default)]
pub struct AmortisedRays(AtomicU64);

impl AmortisedRays {
    /// Counts `rays` more.
    pub fn add(&self, rays: u64) {
        self.0.fetch_add(rays, Ordering::Relaxed);
    }

    /// Rays counted so far.
    pub fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}
