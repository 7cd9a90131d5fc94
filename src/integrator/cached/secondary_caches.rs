//! The secondary caches a rule set holds (`secondary`): each built once,
//! by the first caller that needs it, and shared by every clone.

use std::collections::HashMap;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use crate::cache::IrradianceCache;
use crate::render::{Cancel, PathLimits, RenderError};

/// What identifies one secondary cache of a rule set: the paths its records
/// sum and the options that place them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SecondaryKey {
    pub paths: PathLimits,
    /// Bits of the accuracy and of the radius bounds in pixels.
    pub accuracy: u64,
    pub min_pixels: u64,
    pub max_pixels: u64,
}

/// One secondary cache, frozen; looked up at the accuracy it was placed
/// with (part of its key).
pub struct SecondaryCache {
    pub cache: IrradianceCache,
}

/// A secondary cache being built by one caller, or built.
enum Slot {
    Building,
    Built(Arc<SecondaryCache>),
}

impl Slot {
    fn records(&self) -> u64 {
        match self {
            Slot::Built(built) => built.cache.stats().records,
            Slot::Building => 0,
        }
    }
}

/// The secondary caches of one scene, rule set and cache configuration,
/// each built on first use. Clones share them.
#[derive(Clone, Default)]
pub struct SecondaryCaches {
    slots: Arc<(Mutex<HashMap<SecondaryKey, Slot>>, Condvar)>,
}

/// How often a caller waiting for another's build looks at its own cancel flag.
const CANCEL_POLL: Duration = Duration::from_millis(20);

impl SecondaryCaches {
    /// The cache under `key`, or the one `build` makes now if no one has,
    /// with what `build` reported.
    ///
    /// The build runs on a pool of its own ([`crate::isolated`]), so a caller
    /// that finds it under way simply blocks until it is done (or its own
    /// `cancel` is set). A failed build (one stopped by `cancel` among them)
    /// leaves nothing behind, and the next caller builds it.
    pub fn get_or_build<R: Send>(
        &self,
        key: SecondaryKey,
        cancel: &Cancel,
        build: impl FnOnce() -> Result<(SecondaryCache, R), RenderError> + Send,
    ) -> Result<(Arc<SecondaryCache>, Option<R>), RenderError> {
        let (lock, changed) = &*self.slots;
        let mut slots = lock.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            cancel.check()?;
            match slots.get(&key) {
                Some(Slot::Built(found)) => return Ok((found.clone(), None)),
                Some(Slot::Building) => {}
                None => {
                    slots.insert(key, Slot::Building);
                    break;
                }
            }
            slots = changed
                .wait_timeout(slots, CANCEL_POLL)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        drop(slots);
        // A panicking build must not leave its slot `Building` for ever.
        let built = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            crate::isolated::isolated(build)
        }));
        let mut slots = lock.lock().unwrap_or_else(|e| e.into_inner());
        let built = match built {
            Ok(built) => built,
            Err(panic) => {
                slots.remove(&key);
                changed.notify_all();
                drop(slots);
                std::panic::resume_unwind(panic);
            }
        };
        let outcome = match built {
            Ok((built, report)) => {
                let built = Arc::new(built);
                slots.insert(key, Slot::Built(built.clone()));
                Ok((built, Some(report)))
            }
            Err(e) => {
                slots.remove(&key);
                Err(e)
            }
        };
        changed.notify_all();
        outcome
    }

    /// Records of the caches built so far.
    pub fn records(&self) -> u64 {
        let slots = self.slots.0.lock().unwrap_or_else(|e| e.into_inner());
        slots.values().map(Slot::records).sum()
    }

    /// Drops every cache built so far and returns its records; the next
    /// caller that needs one builds it again (the same records: a build
    /// depends on the scene and configuration alone). A build under way
    /// is left to finish.
    pub fn clear(&self) -> u64 {
        let mut slots = self.slots.0.lock().unwrap_or_else(|e| e.into_inner());
        let records = slots.values().map(Slot::records).sum();
        slots.retain(|_, slot| matches!(slot, Slot::Building));
        records
    }
}
