//! A shape plugin's view of its document's parameters: each read by name
//! into the type the plugin wants, a wrong kind of value refused naming the
//! field (e.g. `shapes[2].radius`).

use crate::scene::error::SceneError;
use crate::scene::format::{ShapeDoc, ShapeParam};

/// The parameters of shape document `doc`, whose field path is `field`.
#[derive(Clone, Copy)]
pub(crate) struct ShapeFields<'a> {
    pub doc: &'a ShapeDoc,
    pub field: &'a str,
}

impl<'a> ShapeFields<'a> {
    /// The field path of parameter `name`.
    pub fn path(&self, name: &str) -> String {
        format!("{}.{name}", self.field)
    }

    fn get(&self, name: &str) -> Option<&'a ShapeParam> {
        self.doc.params.get(name)
    }

    fn wrong(&self, name: &str, expected: &str) -> SceneError {
        SceneError::invalid(self.path(name), format!("expected {expected}"))
    }

    /// A required parameter's absence.
    pub fn missing(&self, name: &str) -> SceneError {
        SceneError::invalid(self.field, format!("missing field `{name}`"))
    }

    pub fn number(&self, name: &str) -> Result<Option<f64>, SceneError> {
        match self.get(name) {
            None => Ok(None),
            Some(ShapeParam::Number(x)) => Ok(Some(*x)),
            Some(_) => Err(self.wrong(name, "a number")),
        }
    }

    pub fn boolean(&self, name: &str) -> Result<Option<bool>, SceneError> {
        match self.get(name) {
            None => Ok(None),
            Some(ShapeParam::Bool(b)) => Ok(Some(*b)),
            Some(_) => Err(self.wrong(name, "true or false")),
        }
    }

    pub fn text(&self, name: &str) -> Result<Option<&'a str>, SceneError> {
        match self.get(name) {
            None => Ok(None),
            Some(ShapeParam::Text(t)) => Ok(Some(t)),
            Some(_) => Err(self.wrong(name, "a string")),
        }
    }

    /// A whole number in `0..=max`.
    pub fn index(&self, name: &str, max: u64) -> Result<Option<u64>, SceneError> {
        match self.number(name)? {
            None => Ok(None),
            Some(x) if x >= 0.0 && x <= max as f64 && x.fract() == 0.0 => Ok(Some(x as u64)),
            Some(x) => Err(SceneError::invalid(
                self.path(name),
                format!("{x} is not a whole number or outside 0..={max}"),
            )),
        }
    }

    /// `[x, y, z]`, finite.
    pub fn vec3(&self, name: &str) -> Result<Option<[f64; 3]>, SceneError> {
        match self.get(name) {
            None => Ok(None),
            Some(ShapeParam::Numbers(v)) if v.len() == 3 => {
                if v.iter().all(|x| x.is_finite()) {
                    Ok(Some([v[0], v[1], v[2]]))
                } else {
                    Err(SceneError::invalid(self.path(name), "not finite"))
                }
            }
            Some(_) => Err(self.wrong(name, "[x, y, z]")),
        }
    }

    /// A list of rows of `arity` numbers (row-major, possibly none).
    pub fn rows(&self, name: &str, arity: usize) -> Result<Option<&'a [f64]>, SceneError> {
        match self.get(name) {
            None => Ok(None),
            Some(ShapeParam::Rows { arity: a, values }) if *a == arity => Ok(Some(values)),
            Some(ShapeParam::Numbers(v)) if v.is_empty() => Ok(Some(v)),
            Some(_) => Err(self.wrong(name, &format!("a list of lists of {arity} numbers"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::format::ShapeDoc;

    fn doc(json: &str) -> ShapeDoc {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn each_value_is_read_into_its_type_or_refused_by_name() {
        let d = doc(
            r#"{"type": "triangles", "material": "m", "positions": [[0, 1, 2], [3, 4, 5]],
                "radius": 2, "filename": "a.obj", "face_normals": true, "center": [1, 2, 3],
                "indices": []}"#,
        );
        let f = ShapeFields {
            doc: &d,
            field: "shapes[1]",
        };
        assert_eq!(
            f.rows("positions", 3).unwrap(),
            Some(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0][..])
        );
        assert_eq!(f.rows("indices", 3).unwrap(), Some(&[][..]));
        assert_eq!(f.number("radius").unwrap(), Some(2.0));
        assert_eq!(f.index("radius", 5).unwrap(), Some(2));
        assert_eq!(f.text("filename").unwrap(), Some("a.obj"));
        assert_eq!(f.boolean("face_normals").unwrap(), Some(true));
        assert_eq!(f.vec3("center").unwrap(), Some([1.0, 2.0, 3.0]));
        assert_eq!(f.number("absent").unwrap(), None);
        for e in [
            f.rows("positions", 2).unwrap_err(),
            f.number("filename").unwrap_err(),
            f.index("radius", 1).unwrap_err(),
            f.vec3("positions").unwrap_err(),
        ] {
            assert!(e.field().unwrap().starts_with("shapes[1]."), "{e}");
        }
    }

    #[test]
    fn ragged_lists_are_refused_where_they_go_wrong() {
        let text = r#"{"type": "triangles", "material": "m", "positions": [[0, 1, 2], [3, 4]]}"#;
        let mut de = serde_json::Deserializer::from_str(text);
        let e = serde_path_to_error::deserialize::<_, ShapeDoc>(&mut de).unwrap_err();
        assert_eq!(e.path().to_string(), "positions[1]");
        assert_eq!(e.inner().column(), 70, "{e}");
        for bad in [
            r#"[1, [2]]"#,
            r#"[[1], 2]"#,
            r#"[[[1]]]"#,
            r#"{"a": 1}"#,
            "null",
        ] {
            let text = format!(r#"{{"type": "sphere", "material": "m", "center": {bad}}}"#);
            assert!(serde_json::from_str::<ShapeDoc>(&text).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_document_serialises_as_it_reads() {
        let text = r#"{"type":"triangles","id":null,"material":"m","to_world":null,"emitter":null,"flip_normals":false,"indices":[[0.0,1.0,2.0]],"positions":[[0.0,0.0,0.0],[1.0,0.0,0.0],[0.0,1.5,0.0]],"uvs":[]}"#;
        assert_eq!(serde_json::to_string(&doc(text)).unwrap(), text);
        let twice = r#"{"type": "sphere", "material": "m", "radius": 1, "radius": 2}"#;
        assert!(serde_json::from_str::<ShapeDoc>(twice).is_err());
        let untyped = r#"{"material": "m"}"#;
        let e = serde_json::from_str::<ShapeDoc>(untyped).unwrap_err();
        assert!(e.to_string().contains("missing field `type`"), "{e}");
    }
}
