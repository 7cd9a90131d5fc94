//! Affine `to_world` transforms: building them from the scene file's
//! operations and checking that they are usable (finite, non-singular).
//!
//! Composition order follows Mitsuba: in a list `[A, B, C]` each later
//! operation applies after the earlier ones, so the matrix is `C·B·A` and a
//! point is first transformed by `A`.

use glam::{DAffine3, DMat3, DMat4, DVec3};

use super::error::SceneError;
use super::format::{TransformDoc, TransformOp, Vec3};

/// Largest accepted |entry| of a matrix or vector in a transform; beyond this
/// products overflow or lose all precision.
const MAX_MAGNITUDE: f64 = 1e12;

/// Checks that every component of `v` is finite and of sane magnitude.
pub(crate) fn check_vec3(v: &Vec3, field: &str) -> Result<DVec3, SceneError> {
    for (i, x) in v.iter().enumerate() {
        if !x.is_finite() || x.abs() > MAX_MAGNITUDE {
            return Err(SceneError::invalid(
                format!("{field}[{i}]"),
                format!("{x} is not a finite number of magnitude ≤ {MAX_MAGNITUDE:e}"),
            ));
        }
    }
    Ok(DVec3::from_array(*v))
}

fn check_scalar(x: f64, field: &str) -> Result<f64, SceneError> {
    if !x.is_finite() || x.abs() > MAX_MAGNITUDE {
        return Err(SceneError::invalid(
            field,
            format!("{x} is not a finite number of magnitude ≤ {MAX_MAGNITUDE:e}"),
        ));
    }
    Ok(x)
}

/// Rotation by `degrees` counter-clockwise looking down `axis` (right-handed).
pub fn rotation(axis: DVec3, degrees: f64) -> Option<DAffine3> {
    let len = axis.length();
    if len.is_finite() && len > 0.0 {
        Some(DAffine3::from_axis_angle(axis / len, degrees.to_radians()))
    } else {
        None
    }
}

/// Mitsuba's `look_at`: columns (left, up, forward, origin) where forward
/// points at `target`, left = up × forward. Local +z maps to the viewing
/// direction, +y towards `up`. `None` when `target == origin` or `up` is
/// parallel to the viewing direction.
pub fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> Option<DAffine3> {
    let forward = (target - origin).try_normalize()?;
    let left = up.cross(forward).try_normalize()?;
    let new_up = forward.cross(left);
    Some(DAffine3::from_mat3_translation(
        DMat3::from_cols(left, new_up, forward),
        origin,
    ))
}

/// Affine transform from a row-major 4×4 matrix; `None` if the last row is
/// not `[0, 0, 0, 1]`.
pub fn from_rows(rows: &[[f64; 4]; 4]) -> Option<DAffine3> {
    if rows[3] != [0.0, 0.0, 0.0, 1.0] {
        return None;
    }
    let m = DMat4::from_cols_array_2d(rows).transpose();
    Some(DAffine3::from_mat4(m))
}

fn op_transform(op: &TransformOp, field: &str) -> Result<DAffine3, SceneError> {
    match op {
        TransformOp::Matrix(rows) => {
            for (r, row) in rows.iter().enumerate() {
                for (c, x) in row.iter().enumerate() {
                    check_scalar(*x, &format!("{field}.matrix[{r}][{c}]"))?;
                }
            }
            from_rows(rows).ok_or_else(|| {
                SceneError::invalid(
                    format!("{field}.matrix[3]"),
                    "the last row of an affine matrix must be [0, 0, 0, 1]",
                )
            })
        }
        TransformOp::Translate(v) => Ok(DAffine3::from_translation(check_vec3(
            v,
            &format!("{field}.translate"),
        )?)),
        TransformOp::Scale(v) => Ok(DAffine3::from_scale(check_vec3(
            v,
            &format!("{field}.scale"),
        )?)),
        TransformOp::Rotate { axis, angle } => {
            let axis = check_vec3(axis, &format!("{field}.rotate.axis"))?;
            let angle = check_scalar(*angle, &format!("{field}.rotate.angle"))?;
            rotation(axis, angle).ok_or_else(|| {
                SceneError::invalid(format!("{field}.rotate.axis"), "axis has zero length")
            })
        }
        TransformOp::LookAt { origin, target, up } => {
            let o = check_vec3(origin, &format!("{field}.look_at.origin"))?;
            let t = check_vec3(target, &format!("{field}.look_at.target"))?;
            let u = check_vec3(up, &format!("{field}.look_at.up"))?;
            look_at(o, t, u).ok_or_else(|| {
                SceneError::invalid(
                    format!("{field}.look_at"),
                    "target equals origin or up is parallel to the viewing direction",
                )
            })
        }
    }
}

/// The composed transform of `doc`, checked to be finite and invertible.
/// `field` is the path of the `to_world` value, used in errors.
pub fn build(doc: &TransformDoc, field: &str) -> Result<DAffine3, SceneError> {
    let mut total = DAffine3::IDENTITY;
    for (i, op) in doc.ops.iter().enumerate() {
        total = op_transform(op, &doc.op_field(field, i))? * total;
    }
    check_invertible(&total, field)?;
    Ok(total)
}

/// Rejects non-finite and singular (zero-scale) transforms.
pub(crate) fn check_invertible(t: &DAffine3, field: &str) -> Result<(), SceneError> {
    let m = t.matrix3;
    let finite = m.is_finite() && t.translation.is_finite();
    let scale = m
        .x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length());
    // |det| relative to the largest axis cubed: 1e-12 means one axis is
    // squashed by 12 orders of magnitude relative to the others.
    if !finite || scale == 0.0 || m.determinant().abs() <= 1e-12 * scale.powi(3) {
        return Err(SceneError::invalid(
            field,
            "transform is singular (a zero scale) or not finite",
        ));
    }
    Ok(())
}

/// Normal transform (inverse transpose of the linear part), so that
/// transformed normals stay perpendicular to transformed surfaces.
pub fn normal_matrix(t: &DAffine3) -> DMat3 {
    t.matrix3.inverse().transpose()
}

/// The uniform scale `s` if `m = s·R` with `R` orthogonal (to 1e-6).
pub(crate) fn similarity_scale(m: &DMat3) -> Option<f64> {
    let cols = [m.x_axis, m.y_axis, m.z_axis];
    let s = cols[0].length();
    let tol = 1e-6 * s * s;
    let ok = cols
        .iter()
        .all(|c| (c.length_squared() - s * s).abs() <= tol)
        && cols[0].dot(cols[1]).abs() <= tol
        && cols[1].dot(cols[2]).abs() <= tol
        && cols[0].dot(cols[2]).abs() <= tol;
    ok.then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec4;

    /// Row-major 4×4 form, so failures print readably.
    fn to_rows(t: &DAffine3) -> [[f64; 4]; 4] {
        let m = DMat4::from(*t).transpose();
        let r = |v: DVec4| v.to_array();
        [r(m.x_axis), r(m.y_axis), r(m.z_axis), r(m.w_axis)]
    }

    fn close(a: &DAffine3, b: &DAffine3) -> bool {
        let (a, b) = (to_rows(a), to_rows(b));
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() < 1e-12)
    }

    fn parse(json: &str) -> TransformDoc {
        serde_json::from_str(json).expect("valid transform JSON")
    }

    #[test]
    fn translate_rotate_scale_compose_in_mitsuba_order() {
        // Scale first, then rotate 90° about z, then translate.
        let doc = parse(
            r#"[{"scale": [2, 3, 4]}, {"rotate": {"axis": [0, 0, 1], "angle": 90}},
                {"translate": [1, 2, 3]}]"#,
        );
        let t = build(&doc, "to_world").unwrap();
        // Explicit matrix: R·S has columns R(2x) = 2y, R(3y) = -3x, 4z.
        let explicit = from_rows(&[
            [0.0, -3.0, 0.0, 1.0],
            [2.0, 0.0, 0.0, 2.0],
            [0.0, 0.0, 4.0, 3.0],
            [0.0, 0.0, 0.0, 1.0],
        ])
        .unwrap();
        assert!(close(&t, &explicit), "{:?}", to_rows(&t));
        let p = t.transform_point3(DVec3::new(1.0, 1.0, 1.0));
        assert!((p - DVec3::new(-2.0, 4.0, 7.0)).length() < 1e-12);
    }

    #[test]
    fn a_single_object_equals_a_one_element_list() {
        let one = build(&parse(r#"{"translate": [1, 2, 3]}"#), "t").unwrap();
        let list = build(&parse(r#"[{"translate": [1, 2, 3]}]"#), "t").unwrap();
        assert!(close(&one, &list));
    }

    #[test]
    fn look_at_maps_local_axes_like_mitsuba() {
        let t = look_at(DVec3::new(0.0, 0.0, 3.9), DVec3::ZERO, DVec3::Y).unwrap();
        // Mitsuba's Cornell box camera: diag(-1, 1, -1) with origin (0, 0, 3.9).
        let expected = from_rows(&[
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0, 3.9],
            [0.0, 0.0, 0.0, 1.0],
        ])
        .unwrap();
        assert!(close(&t, &expected));
        assert!(look_at(DVec3::ZERO, DVec3::ZERO, DVec3::Y).is_none());
        assert!(look_at(DVec3::ZERO, DVec3::Y, DVec3::Y).is_none());
    }

    #[test]
    fn bad_transforms_name_the_field() {
        let err = build(&parse(r#"[{"scale": [1, 0, 1]}]"#), "shapes[0].to_world").unwrap_err();
        assert_eq!(err.field(), Some("shapes[0].to_world"));
        let err = build(
            &parse(r#"[{"translate": [0, 0, 0]}, {"rotate": {"axis": [0, 0, 0], "angle": 3}}]"#),
            "s.to_world",
        )
        .unwrap_err();
        assert_eq!(err.field(), Some("s.to_world[1].rotate.axis"));
        let err = build(
            &parse(r#"{"matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[1,0,0,1]]}"#),
            "t",
        )
        .unwrap_err();
        assert_eq!(err.field(), Some("t.matrix[3]"));
        let err = build(
            &parse(r#"{"matrix": [[1,0,0,0],[0,1,1e300,0],[0,0,1,0],[0,0,0,1]]}"#),
            "t",
        )
        .unwrap_err();
        assert_eq!(err.field(), Some("t.matrix[1][2]"));
    }
}
