//! What a cancelled light-transport call returns: [`Cancel::check`] between
//! items, `Err(RenderError::Cancelled)` once the flag is set (the flag
//! itself is the crate's, `crate::cancel`).

pub use crate::cancel::Cancel;

use super::error::RenderError;

impl Cancel {
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
    fn a_cancelled_flag_checks_as_cancelled() {
        let a = Cancel::new();
        assert!(a.check().is_ok());
        a.cancel();
        assert_eq!(a.check(), Err(RenderError::Cancelled));
    }
}
