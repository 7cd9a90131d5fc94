//! `<integrator>`: requests and presets choose the method (the integrator's
//! other settings are the service's to choose), but two settings change
//! what the scene looks like, so they become the scene's:
//! - `hide_emitters` (`Scene::hide_emitters`);
//! - `max_depth`, the longest path counted from the camera, which becomes
//!   the scene's default depth (`Scene::max_depth`). Mitsuba's `-1`
//!   (unbounded) leaves the service's default; `direct` renders paths of
//!   two segments (emission seen, then direct light), so it means 2.
//!
//! Wrappers that only add outputs (`aov`, `moment`) take these settings
//! from the integrator they nest.

use super::parse::Element;
use super::props::Props;
use super::{Ctx, XmlError};

/// What an `<integrator>` says about the picture.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub(crate) struct IntegratorSettings {
    pub hide_emitters: bool,
    /// Segments from the camera; `None`: the service's default.
    pub max_depth: Option<u32>,
}

/// The settings of integrator element `el`.
pub(crate) fn settings<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
) -> Result<IntegratorSettings, XmlError> {
    let mut props = Props::new(el);
    let hide_emitters = props.boolean("hide_emitters", false)?;
    let depth = props.int(
        "max_depth",
        -1,
        -1..=i64::from(crate::scene::MAX_PATH_DEPTH),
    )?;
    if depth == 0
        && let Some(c) = props.get("max_depth")?
    {
        return Err(c.error("value", "0 renders nothing: give 1 or more, or -1"));
    }
    let mut max_depth = match el.attr("type") {
        Some("direct") => Some(2),
        _ => u32::try_from(depth).ok().filter(|&d| d >= 1),
    };
    let mut hide_nested = false;
    for c in el.children.iter().filter(|c| c.tag == "integrator") {
        let nested = settings(ctx, c)?;
        max_depth = max_depth.or(nested.max_depth);
        hide_nested |= nested.hide_emitters;
    }
    // The rest (samplers' settings, Russian roulette depth, …) is the
    // service's to decide per request.
    for c in &el.children {
        let name = c.attr("name").unwrap_or_default();
        if !matches!(name, "hide_emitters" | "max_depth") {
            props.ignore(&[name]);
        }
    }
    props.ignore_tags(&["integrator"]);
    props.finish(ctx)?;
    Ok(IntegratorSettings {
        hide_emitters: hide_emitters || hide_nested,
        max_depth,
    })
}
