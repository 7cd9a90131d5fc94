//! What one scene load may hold and when it must stop: every reader
//! reserves the bytes it is about to allocate (decoded meshes, images, the
//! built geometry) from the load's [`Budget`] before allocating them, so a
//! small file that claims a large payload (a PLY header, a serialized
//! mesh's counts, an image's size) is refused before the memory is taken,
//! and the readers ask its cancel flag between files, materials and chunks
//! of a mesh.
//!
//! The budget counts what the load holds at once: the meshes it read and
//! the images it decoded while the scene is built from them, then the
//! built geometry. That is at least what the finished scene holds
//! (`Scene::heap_bytes`), so a scene that loads within a budget also stays
//! within it once built.

use std::sync::atomic::{AtomicU64, Ordering};

use super::MAX_SCENE_MEMORY_BYTES;
use super::error::SceneError;
use crate::cancel::Cancel;

/// The bounds a caller puts on one scene load.
#[derive(Clone, Debug)]
pub struct LoadLimits {
    /// Most bytes the load may hold at once (module docs); at most
    /// [`MAX_SCENE_MEMORY_BYTES`], the library's own bound on one scene.
    pub max_bytes: u64,
    /// The name of the budget `max_bytes` comes from, for the error that
    /// refuses a scene over it (the service's remaining
    /// `scenes.max_scene_bytes`, or `MAX_SCENE_MEMORY_BYTES`).
    pub budget: &'static str,
    /// Stops the load between items once set.
    pub cancel: Cancel,
}

impl Default for LoadLimits {
    /// The library's bound on one scene, never cancelled.
    fn default() -> Self {
        LoadLimits {
            max_bytes: MAX_SCENE_MEMORY_BYTES,
            budget: "MAX_SCENE_MEMORY_BYTES",
            cancel: Cancel::never(),
        }
    }
}

/// One load's reservations against its [`LoadLimits`]; shared by the
/// threads that read its files in parallel.
pub(crate) struct Budget {
    limit: u64,
    name: &'static str,
    held: AtomicU64,
    cancel: Cancel,
}

impl Budget {
    pub(crate) fn new(limits: &LoadLimits) -> Self {
        let (limit, name) = match limits.max_bytes < MAX_SCENE_MEMORY_BYTES {
            true => (limits.max_bytes, limits.budget),
            false => (MAX_SCENE_MEMORY_BYTES, "MAX_SCENE_MEMORY_BYTES"),
        };
        Budget {
            limit,
            name,
            held: AtomicU64::new(0),
            cancel: limits.cancel.clone(),
        }
    }

    /// Takes `bytes` for `what` (e.g. "12000000 vertices"), which the
    /// scene's `field` asks for; refused, with nothing taken, when the
    /// load would then hold more than its limit.
    pub(crate) fn reserve(&self, bytes: u64, field: &str, what: &str) -> Result<(), SceneError> {
        let mut held = self.held.load(Ordering::Relaxed);
        loop {
            let total = held.saturating_add(bytes);
            if total > self.limit {
                return Err(SceneError::OverBudget {
                    field: field.to_owned(),
                    budget: self.name,
                    message: format!(
                        "{what} take {bytes} bytes, which would bring the scene to {total} bytes, over its {} bytes ({})",
                        self.limit, self.name
                    ),
                });
            }
            match self
                .held
                .compare_exchange_weak(held, total, Ordering::Relaxed, Ordering::Relaxed)
            {
                Ok(_) => return Ok(()),
                Err(now) => held = now,
            }
        }
    }

    /// Gives back `bytes` reserved for something freed since.
    pub(crate) fn release(&self, bytes: u64) {
        let _ = self
            .held
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |held| {
                Some(held.saturating_sub(bytes))
            });
    }

    /// `Err(SceneError::Cancelled)` once the load's flag is set.
    pub(crate) fn check_cancel(&self) -> Result<(), SceneError> {
        if self.cancel.is_cancelled() {
            Err(SceneError::Cancelled)
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reservations_past_the_limit_are_refused_and_take_nothing() {
        let limits = LoadLimits {
            max_bytes: 100,
            budget: "scenes.max_scene_bytes",
            cancel: Cancel::new(),
        };
        let budget = Budget::new(&limits);
        budget.reserve(60, "a", "sixty").unwrap();
        let err = budget.reserve(41, "shapes[1]", "41 texels").unwrap_err();
        assert_eq!(err.field(), Some("shapes[1]"));
        assert!(err.to_string().contains("scenes.max_scene_bytes"), "{err}");
        budget.reserve(40, "b", "forty").unwrap();
        budget.release(50);
        budget.reserve(50, "c", "fifty").unwrap();
        assert!(budget.check_cancel().is_ok());
        limits.cancel.cancel();
        assert!(matches!(budget.check_cancel(), Err(SceneError::Cancelled)));
    }
}
