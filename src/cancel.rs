//! Cooperative cancellation of long library calls: a shared flag that the
//! service sets when a request is gone (deadline passed or client
//! disconnected) and that every loop which may run for long asks between
//! items (the pixels of a tile, the records of a placement pass, the points
//! of a query, the files and materials of a scene load). The CLI and the
//! tests pass [`Cancel::never`].
//!
//! It lives below every layer, as scenes are loaded under it as well as
//! rendered; each layer says what a cancelled call returns
//! (`render::RenderError::Cancelled`, `scene::SceneError::Cancelled`).
//!
//! A check is one relaxed atomic load, so it costs nothing beside a pixel's
//! or a point's work; items are short (bounded by the request limits), so a
//! cancelled call returns within one item's time.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_flag_and_never_stays_clear() {
        let a = Cancel::new();
        let b = a.clone();
        assert!(!b.is_cancelled());
        a.cancel();
        assert!(b.is_cancelled());
        let never = Cancel::never();
        never.cancel();
        assert!(!never.is_cancelled());
    }
}
