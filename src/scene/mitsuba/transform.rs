//! `<transform name="to_world">` → the document's transform operations, in
//! document order (each later operation applies after the earlier ones, as
//! in Mitsuba and in the JSON format). Values are checked by the shared
//! loader (finite, magnitude ≤ 1e12, invertible); its errors are mapped back
//! to the operation's line through the recorded origins.

use glam::DVec3;

use super::parse::Element;
use super::props::{numbers, vec3};
use super::{Ctx, Origin, XmlError};
use crate::scene::format::{TransformDoc, TransformOp};
use crate::sphere::Frame;

/// Operations with the element each came from.
#[derive(Clone, Default)]
pub(crate) struct Ops {
    ops: Vec<TransformOp>,
    origins: Vec<Origin>,
}

fn three(el: &Element, attr: &str) -> Result<[f64; 3], XmlError> {
    match numbers(el, attr)?[..] {
        [x, y, z] => Ok([x, y, z]),
        ref v => Err(el.error(attr, format!("expected 3 numbers, found {}", v.len()))),
    }
}

/// A `<lookat>`'s `up`, or where it is absent or zero, Mitsuba 3's choice:
/// the first tangent of its coordinate system about the viewing direction
/// (`coordinate_system`, Duff et al.'s basis, [`Frame::from_normal`]). A
/// view of zero length keeps the zero, which the loader refuses.
fn up_or_default(up: [f64; 3], origin: [f64; 3], target: [f64; 3]) -> [f64; 3] {
    let view = (DVec3::from(target) - DVec3::from(origin)).normalize_or_zero();
    match up == [0.0; 3] && view != DVec3::ZERO {
        true => Frame::from_normal(view).s.to_array(),
        false => up,
    }
}

fn op(c: &Element) -> Result<TransformOp, XmlError> {
    Ok(match c.tag.as_str() {
        "translate" => TransformOp::Translate(vec3(c, 0.0)?),
        "scale" => match c.attr("value") {
            Some(_) => match numbers(c, "value")?[..] {
                [s] => TransformOp::Scale([s; 3]),
                [x, y, z] => TransformOp::Scale([x, y, z]),
                ref v => {
                    return Err(c.error(
                        "value",
                        format!("expected 1 or 3 numbers, found {}", v.len()),
                    ));
                }
            },
            None => TransformOp::Scale(vec3(c, 1.0)?),
        },
        "rotate" => TransformOp::Rotate {
            axis: vec3(c, 0.0)?,
            angle: super::props::number(c, "angle")?,
        },
        "matrix" => {
            let v = numbers(c, "value")?;
            let rows = match v.len() {
                16 => std::array::from_fn(|r| std::array::from_fn(|k| v[4 * r + k])),
                9 => std::array::from_fn(|r| {
                    std::array::from_fn(|k| match (r, k) {
                        (3, 3) => 1.0,
                        (3, _) | (_, 3) => 0.0,
                        _ => v[3 * r + k],
                    })
                }),
                n => {
                    return Err(c.error(
                        "value",
                        format!("a matrix needs 16 (4×4) or 9 (3×3) numbers, found {n}"),
                    ));
                }
            };
            TransformOp::Matrix(rows)
        }
        "lookat" => {
            let (origin, target) = (three(c, "origin")?, three(c, "target")?);
            let up = match c.attr("up") {
                Some(_) => three(c, "up")?,
                None => [0.0; 3],
            };
            TransformOp::LookAt {
                origin,
                target,
                up: up_or_default(up, origin, target),
            }
        }
        other => {
            return Err(c.error(
                "",
                format!(
                    "<{other}> is not a transform operation (translate, rotate, scale, matrix, lookat)"
                ),
            ));
        }
    })
}

impl Ops {
    /// Reads a `<transform>` element.
    pub fn read(el: &Element) -> Result<Ops, XmlError> {
        if el.tag != "transform" {
            return Err(el.error("", "a transform property must be a <transform>"));
        }
        let mut out = Ops::default();
        for c in &el.children {
            out.ops.push(op(c)?);
            out.origins.push(Origin::of(c));
        }
        Ok(out)
    }

    /// `self` followed by `outer` (e.g. a shape inside an instance).
    pub fn then(&self, outer: &Ops) -> Ops {
        let mut out = self.clone();
        out.ops.extend(outer.ops.iter().cloned());
        out.origins.extend(outer.origins.iter().cloned());
        out
    }

    /// The document value for field `field` (None = identity), recording
    /// where each operation came from.
    pub fn into_doc(self, ctx: &mut Ctx, field: &str) -> Option<TransformDoc> {
        for (i, o) in self.origins.iter().enumerate() {
            ctx.origins.push((format!("{field}[{i}]"), o.clone()));
        }
        self.doc()
    }

    /// The document value (None = identity).
    pub fn doc(self) -> Option<TransformDoc> {
        (!self.ops.is_empty()).then_some(TransformDoc {
            ops: self.ops,
            single: false,
        })
    }
}
