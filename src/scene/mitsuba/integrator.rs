//! `<integrator>`: requests and presets choose the method and `max_depth`
//! (the integrator's other settings are the service's to choose), but
//! `hide_emitters` changes what the scene looks like, so it becomes the
//! scene's (`Scene::hide_emitters`).

use super::parse::Element;
use super::props::Props;
use super::{Ctx, XmlError};

/// The `hide_emitters` of integrator element `el` (false if absent).
pub(crate) fn hide_emitters<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<bool, XmlError> {
    let mut props = Props::new(el);
    let hide = props.boolean("hide_emitters", false)?;
    // What the service decides per request, and nested integrators (AOVs,
    // moment) that only add outputs.
    for c in &el.children {
        if c.attr("name") != Some("hide_emitters") {
            props.ignore(&[c.attr("name").unwrap_or_default()]);
        }
    }
    props.ignore_tags(&["integrator"]);
    props.finish(ctx)?;
    Ok(hide)
}
