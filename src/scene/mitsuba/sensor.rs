//! `<sensor type="perspective">` (or `thinlens`, `orthographic`) with its
//! `<film>` → the document camera.
//! `fov_axis` `x`, `y`, `smaller`, `larger` map directly; `diagonal` and
//! `focal_length` (35 mm equivalent, Mitsuba's default "50mm") are converted
//! to a horizontal field of view, as Mitsuba's `parse_fov` does. The film
//! gives the size and the reconstruction filter (`scene::pixel_filter`).
//! Sampler and clip planes do not change the scene and are ignored.

use crate::scene::format::{CameraDoc, CameraKind, FilterDoc, FovAxis, TransformDoc};

use super::parse::{Element, quote};
use super::props::Props;
use super::transform::Ops;
use super::{Ctx, XmlError};

/// Mitsuba's default film size.
const DEFAULT_SIZE: (u32, u32) = (768, 576);
/// Mitsuba's default focal length, mm (35 mm film equivalent).
const DEFAULT_FOCAL_LENGTH: f64 = 50.0;

const IDENTITY: TransformDoc = TransformDoc {
    ops: Vec::new(),
    single: false,
};

/// Horizontal full field of view (degrees) for a full diagonal one.
fn fov_x_from_diagonal(diagonal_deg: f64, width: u32, height: u32) -> f64 {
    let aspect = width as f64 / height as f64;
    let tan_x = (diagonal_deg.to_radians() * 0.5).tan() / (1.0 + 1.0 / (aspect * aspect)).sqrt();
    2.0 * tan_x.atan().to_degrees()
}

/// Full diagonal field of view (degrees) of a 36×24 mm frame behind a lens
/// of focal length `mm`.
fn diagonal_fov_of_focal_length(mm: f64) -> f64 {
    2.0 * ((36.0f64 * 36.0 + 24.0 * 24.0).sqrt() / (2.0 * mm))
        .atan()
        .to_degrees()
}

/// Mitsuba's default sensor: at the origin looking along +z, 50 mm lens,
/// 768×576.
pub(crate) fn default_camera() -> CameraDoc {
    let (width, height) = DEFAULT_SIZE;
    CameraDoc {
        kind: CameraKind::Perspective,
        fov: Some(fov_x_from_diagonal(
            diagonal_fov_of_focal_length(DEFAULT_FOCAL_LENGTH),
            width,
            height,
        )),
        fov_axis: FovAxis::X,
        width,
        height,
        to_world: Some(IDENTITY),
        origin: None,
        target: None,
        up: None,
        aperture_radius: None,
        focus_distance: None,
        // Mitsuba's films filter with a Gaussian unless told otherwise.
        filter: Some(FilterDoc::Gaussian { stddev: None }),
    }
}

pub(crate) fn camera<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<CameraDoc, XmlError> {
    let mut props = Props::new(el);
    let (kind, aperture_radius, focus_distance) = match el.attr("type").unwrap_or("") {
        "perspective" => {
            // Every projective camera takes it; a pinhole has no use for it.
            props.ignore(&["focus_distance"]);
            (CameraKind::Perspective, None, None)
        }
        "orthographic" => (CameraKind::Orthographic, None, None),
        "thinlens" => (
            CameraKind::Thinlens,
            Some(props.opt_float("aperture_radius")?.ok_or_else(|| {
                el.error("aperture_radius", "a thinlens needs `aperture_radius`")
            })?),
            props.opt_float("focus_distance")?,
        ),
        other => {
            return Err(el.error(
                "type",
                format!(
                    "sensor type {} is not supported (perspective, thinlens, orthographic)",
                    quote(other)
                ),
            ));
        }
    };
    let (width, height, filter) = match props.nested(ctx, "film")?[..] {
        [] => (
            DEFAULT_SIZE.0,
            DEFAULT_SIZE.1,
            FilterDoc::Gaussian { stddev: None },
        ),
        [film] => read_film(ctx, film)?,
        _ => return Err(el.error("film", "a sensor takes one <film>")),
    };
    let (fov, fov_axis) = match kind {
        // Its image is sized by `to_world`'s scale.
        CameraKind::Orthographic => (None, FovAxis::X),
        _ => {
            let (fov, axis) = field_of_view(&mut props, el, width, height)?;
            (Some(fov), axis)
        }
    };
    let to_world = match props.get("to_world")? {
        Some(t) => Ops::read(t)?,
        None => Ops::default(),
    };
    props.ignore(&["near_clip", "far_clip", "shutter_open", "shutter_close"]);
    props.ignore_tags(&["sampler"]);
    let media = props.nested(ctx, "medium")?;
    ctx.media(&media)?;
    props.finish(ctx)?;
    ctx.origin("camera", el);
    Ok(CameraDoc {
        kind,
        aperture_radius,
        focus_distance,
        fov,
        fov_axis,
        width,
        height,
        // Mitsuba's default pose is the identity.
        to_world: Some(
            to_world
                .into_doc(ctx, "camera.to_world")
                .unwrap_or(IDENTITY),
        ),
        origin: None,
        target: None,
        up: None,
        filter: Some(filter),
    })
}

/// The horizontal field of view of a perspective sensor, degrees, and the
/// axis it is along: `fov` along `fov_axis`, or a 35 mm-equivalent
/// `focal_length` (default "50mm"), as Mitsuba's `parse_fov` reads them.
fn field_of_view<'a>(
    props: &mut Props<'a>,
    el: &'a Element,
    width: u32,
    height: u32,
) -> Result<(f64, FovAxis), XmlError> {
    let fov = props.opt_float("fov")?;
    let focal = props.string("focal_length")?;
    let axis = props.string("fov_axis")?;
    Ok(match (fov, focal) {
        (Some(_), Some(_)) => {
            return Err(el.error("fov", "give either `fov` or `focal_length`, not both"));
        }
        (Some(fov), None) => match axis.unwrap_or("x") {
            "x" => (fov, FovAxis::X),
            "y" => (fov, FovAxis::Y),
            "smaller" => (fov, FovAxis::Smaller),
            "larger" => (fov, FovAxis::Larger),
            "diagonal" => (fov_x_from_diagonal(fov, width, height), FovAxis::X),
            other => {
                return Err(el.error(
                    "fov_axis",
                    format!("{} is not x, y, diagonal, smaller or larger", quote(other)),
                ));
            }
        },
        (None, focal) => {
            let text = focal.unwrap_or("50mm");
            let mm: f64 = text
                .trim()
                .trim_end_matches("mm")
                .parse()
                .ok()
                .filter(|f: &f64| *f > 0.0 && f.is_finite())
                .ok_or_else(|| {
                    el.error(
                        "focal_length",
                        format!("{} is not a length like \"50mm\"", quote(text)),
                    )
                })?;
            let diagonal = diagonal_fov_of_focal_length(mm);
            (fov_x_from_diagonal(diagonal, width, height), FovAxis::X)
        }
    })
}

/// The film's size and reconstruction filter.
fn read_film<'a>(ctx: &mut Ctx<'a>, film: &'a Element) -> Result<(u32, u32, FilterDoc), XmlError> {
    let mut props = Props::new(film);
    let max = i64::from(u32::MAX);
    let width = props.int("width", DEFAULT_SIZE.0.into(), 1..=max)?;
    let height = props.int("height", DEFAULT_SIZE.1.into(), 1..=max)?;
    props.ignore(&[
        "pixel_format",
        "component_format",
        "file_format",
        "sample_border",
        "compensate",
        "banner",
    ]);
    // Mitsuba's default is a Gaussian of standard deviation 0.5 pixel.
    let filter = match props.nested(ctx, "rfilter")?[..] {
        [] => FilterDoc::Gaussian { stddev: None },
        [filter] => reconstruction_filter(ctx, filter)?,
        _ => return Err(film.error("rfilter", "a film takes one <rfilter>")),
    };
    props.finish(ctx)?;
    // In range by construction.
    Ok((width as u32, height as u32, filter))
}

/// A film's `<rfilter>`: box, gaussian (`stddev`) and tent (`radius`) as
/// Mitsuba has them; filters with negative lobes (mitchell, catmullrom,
/// lanczos) cannot be importance sampled and are approximated by a box,
/// said once.
fn reconstruction_filter<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<FilterDoc, XmlError> {
    let mut props = Props::new(el);
    let filter = match el.attr("type").unwrap_or("") {
        "box" => {
            if let Some(radius) = props.opt_float("radius")?
                && radius != 0.5
            {
                ctx.warn(
                    el,
                    format!("a box filter of radius {radius} is approximated by one of radius 0.5 (each pixel's mean radiance)"),
                );
            }
            FilterDoc::Box
        }
        "gaussian" => FilterDoc::Gaussian {
            stddev: props.opt_float("stddev")?,
        },
        "tent" => FilterDoc::Tent {
            radius: props.opt_float("radius")?,
        },
        kind => {
            ctx.warn(
                el,
                format!("a {kind} reconstruction filter is approximated by a box (each pixel's mean radiance)"),
            );
            props.ignore(&["radius", "B", "C", "lobes"]);
            FilterDoc::Box
        }
    };
    props.finish(ctx)?;
    Ok(filter)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_fov_of_a_square_image() {
        // Square image: tan(x/2) = tan(d/2) / √2.
        let x = fov_x_from_diagonal(90.0, 10, 10);
        assert!(((x.to_radians() * 0.5).tan() - 1.0 / 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn fifty_millimetre_lens() {
        // 43.27 mm diagonal, 50 mm focal length: 46.79° diagonally.
        assert!((diagonal_fov_of_focal_length(50.0) - 46.793).abs() < 1e-3);
    }
}
