//! Cooperative cancellation of long library calls.
//!
//! The library cannot be interrupted from outside, so every loop that may
//! run for long (the pixels of a tile, the records of a placement pass, the
//! points of a query) asks [`Cancel::is_cancelled`] between items and stops
//! with [`RenderError::Cancelled`]. The service cancels a job when its
//! request is gone (deadline passed or client disconnected); the CLI and the
//! tests pass [`Cancel::never`].
//!
//! A check is one relaxed atomic load, so it costs nothing beside a pixel's
//! or a point's work; items are short (bounded by the request limits), so a
//! cancelled call returns within one item's time.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use super::error::RenderError;

/// A shared flag: once set, every holder sees it. Clones share the flag.
#[derive(Clone, Debug, Default)]
pub struct Cancel(Option<Arc<AtomicBool>>);

impl Cancel {
    /// A flag that can be set with [`Cancel::cancel`].
    pub fn new() -> Cancel {
        Cancel(Some(Arc::new(AtomicBool::new(false))))
    }

    /// A flag that is never set (for callers that run to completion).
    pub fn never() -> Cancel {
        Cancel(None)
    }

    /// Asks every holder to stop.
    pub fn cancel(&self) {
        if let Some(flag) = &self.0 {
            flag.store(true, Ordering::Relaxed);
        }
    }

    /// Whether [`Cancel::cancel`] was called on this flag or a clone.
    #[inline]
    pub fn is_cancelled(&self) -> bool {
        self.0.as_ref().is_some_and(|f| f.load(Ordering::Relaxed))
    }

    /// `Err(RenderError::Cancelled)` once cancelled.
    #[inline]
    pub fn check(&self) -> Result<(), RenderError> {
        if self.is_cancelled() {
            Err(RenderError::Cancelled)
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_flag_and_never_stays_clear() {
        let a = Cancel::new();
        let b = a.clone();
        assert!(b.check().is_ok());
        a.cancel();
        assert!(b.is_cancelled());
        assert_eq!(b.check(), Err(RenderError::Cancelled));
        let never = Cancel::never();
        never.cancel();
        assert!(!never.is_cancelled());
    }
}
