//! A plugin document's parameters (a material's, a light's), taken one by
//! one by the plugin that parses them; whatever no plugin took is refused
//! by [`Params::finish`], naming its field.

use std::any::Any;

use serde_json::{Map, Value};

use super::bitmap::Bitmaps;
use super::error::SceneError;

/// A linear RGB triple.
use crate::color::RgbArray;

/// The parameters of one plugin document (or of a BSDF nested in one),
/// `field` its path for messages.
pub(crate) struct Params<'a> {
    field: String,
    map: Map<String, Value>,
    /// Where bitmap textures are read; `None` when only the parameters'
    /// names are wanted.
    bitmaps: Option<&'a Bitmaps<'a>>,
    /// What the document declared before this plugin that its parameters
    /// may name (the materials before this one, for nested references),
    /// opaque here: the plugin that reads such a parameter knows its type
    /// ([`Params::declared`]). `None` when only the names are wanted.
    declared: Option<&'a (dyn Any + Sync)>,
}

/// One entry of a list of nested plugin documents ([`Params::nested`]).
pub(crate) enum Nested<'a> {
    /// A document: its `type` and parameters.
    Document(String, Params<'a>),
    /// The id of something declared before, shared rather than copied.
    Reference(String),
}

impl<'a> Params<'a> {
    pub fn new(field: &str, map: Map<String, Value>) -> Self {
        Self {
            field: field.to_string(),
            map,
            bitmaps: None,
            declared: None,
        }
    }

    /// Parameters that may name what `declared` holds.
    pub fn with_declared(mut self, declared: &'a (dyn Any + Sync)) -> Self {
        self.declared = Some(declared);
        self
    }

    /// What the document declared before, if it is a `T`; `None` when only
    /// the parameters' names are wanted.
    pub fn declared<T: Any>(&self) -> Option<&'a T> {
        let declared: &'a dyn Any = self.declared?;
        declared.downcast_ref()
    }

    /// Parameters whose bitmap textures are read through `bitmaps`.
    pub fn with_bitmaps(mut self, bitmaps: &'a Bitmaps<'a>) -> Self {
        self.bitmaps = Some(bitmaps);
        self
    }

    /// The parameters of a document nested in this one, at `field`.
    pub fn nested_params(&self, field: &str, map: Map<String, Value>) -> Params<'a> {
        Params {
            field: field.to_string(),
            map,
            bitmaps: self.bitmaps,
            declared: self.declared,
        }
    }

    pub fn bitmaps(&self) -> Option<&'a Bitmaps<'a>> {
        self.bitmaps
    }

    /// The path of parameter `name`.
    pub fn field(&self, name: &str) -> String {
        format!("{}.{name}", self.field)
    }

    pub fn invalid(&self, name: &str, reason: impl Into<String>) -> SceneError {
        SceneError::invalid(self.field(name), reason)
    }

    /// Refuses every parameter no plugin took.
    pub fn finish(self) -> Result<(), SceneError> {
        match self.map.keys().next() {
            Some(name) => Err(self.invalid(name, "not a parameter of this type")),
            None => Ok(()),
        }
    }

    /// The names of the parameters no plugin took yet.
    pub fn remaining(&self) -> Vec<String> {
        self.map.keys().cloned().collect()
    }

    /// Parameter `name` as given, left in place.
    pub fn peek(&self, name: &str) -> Option<&Value> {
        self.map.get(name)
    }

    /// Parameter `name` as given, taken (for a parser of its own).
    pub fn take(&mut self, name: &str) -> Option<Value> {
        self.map.remove(name)
    }

    /// A finite number, if given.
    pub fn number(&mut self, name: &str) -> Result<Option<f64>, SceneError> {
        match self.take(name) {
            None => Ok(None),
            Some(v) => match v.as_f64() {
                Some(x) if x.is_finite() => Ok(Some(x)),
                _ => Err(self.invalid(name, format!("{v} is not a finite number"))),
            },
        }
    }

    /// A finite vector `[x, y, z]`, if given.
    pub fn vector(&mut self, name: &str) -> Result<Option<[f64; 3]>, SceneError> {
        let Some(v) = self.take(name) else {
            return Ok(None);
        };
        let xyz: Option<Vec<f64>> = v
            .as_array()
            .filter(|a| a.len() == 3)
            .map(|a| a.iter().filter_map(Value::as_f64).collect());
        match xyz {
            Some(c) if c.len() == 3 && c.iter().all(|x| x.is_finite()) => {
                Ok(Some([c[0], c[1], c[2]]))
            }
            _ => Err(self.invalid(name, format!("{v} is not a finite [x, y, z]"))),
        }
    }

    /// A unit direction from a non-zero finite vector, if given.
    pub fn direction(&mut self, name: &str) -> Result<Option<[f64; 3]>, SceneError> {
        let Some(v) = self.vector(name)? else {
            return Ok(None);
        };
        let length = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(length > 0.0 && length.is_finite()) {
            return Err(self.invalid(name, "is not a direction (zero length)"));
        }
        Ok(Some(v.map(|x| x / length)))
    }

    /// A colour: a number (grey) or `[r, g, b]`, each finite and ≥ 0.
    pub fn color(&mut self, name: &str) -> Result<Option<RgbArray>, SceneError> {
        let Some(v) = self.take(name) else {
            return Ok(None);
        };
        let rgb = match &v {
            Value::Number(n) => n.as_f64().map(|x| [x; 3]),
            Value::Array(a) if a.len() == 3 => {
                let c: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
                (c.len() == 3).then(|| [c[0], c[1], c[2]])
            }
            _ => None,
        };
        let Some(rgb) = rgb else {
            return Err(self.invalid(name, format!("{v} is not a number or [r, g, b]")));
        };
        for (i, x) in rgb.iter().enumerate() {
            if !x.is_finite() || *x < 0.0 {
                return Err(SceneError::invalid(
                    format!("{}[{i}]", self.field(name)),
                    format!("{x} is not a finite non-negative value"),
                ));
            }
        }
        Ok(Some(rgb))
    }

    /// A colour that scales reflected or transmitted light: in [0, 1] per
    /// channel, `default` when absent.
    pub fn albedo(&mut self, name: &str, default: RgbArray) -> Result<RgbArray, SceneError> {
        let Some(rgb) = self.color(name)? else {
            return Ok(default);
        };
        match rgb.iter().position(|x| *x > 1.0) {
            Some(i) => Err(SceneError::invalid(
                format!("{}[{i}]", self.field(name)),
                format!("{} is not an albedo in [0, 1]", rgb[i]),
            )),
            None => Ok(rgb),
        }
    }

    /// The error of a required parameter `name` that is absent.
    pub fn missing(&self, name: &str) -> SceneError {
        SceneError::invalid(&self.field, format!("missing field `{name}`"))
    }

    /// [`Self::albedo`] that must be given.
    pub fn required_albedo(&mut self, name: &str) -> Result<RgbArray, SceneError> {
        if !self.map.contains_key(name) {
            return Err(self.missing(name));
        }
        self.albedo(name, [0.0; 3])
    }

    /// A boolean, `default` when absent.
    pub fn boolean(&mut self, name: &str, default: bool) -> Result<bool, SceneError> {
        match self.take(name) {
            None => Ok(default),
            Some(Value::Bool(b)) => Ok(b),
            Some(v) => Err(self.invalid(name, format!("{v} is not true or false"))),
        }
    }

    /// A string, if given.
    pub fn string(&mut self, name: &str) -> Result<Option<String>, SceneError> {
        match self.take(name) {
            None => Ok(None),
            Some(Value::String(s)) => Ok(Some(s)),
            Some(v) => Err(self.invalid(name, format!("{v} is not a string"))),
        }
    }

    /// The plugins nested under `name` (an object or a list whose items are
    /// objects, each with its own `type`, or ids of what was declared
    /// before), with their paths.
    pub fn nested(&mut self, name: &str) -> Result<Vec<(String, Nested<'a>)>, SceneError> {
        let items = match self.take(name) {
            None => Vec::new(),
            Some(Value::Array(items)) => items,
            Some(item) => vec![item],
        };
        items
            .into_iter()
            .enumerate()
            .map(|(i, item)| {
                let field = format!("{}[{i}]", self.field(name));
                let mut map = match item {
                    Value::Object(map) => map,
                    Value::String(id) => return Ok((field, Nested::Reference(id))),
                    _ => {
                        return Err(SceneError::invalid(
                            field,
                            "neither a material object nor the id of one declared before",
                        ));
                    }
                };
                let kind = match map.remove("type") {
                    Some(Value::String(kind)) => kind,
                    _ => return Err(SceneError::invalid(field, "missing field `type`")),
                };
                let params = self.nested_params(&field, map);
                Ok((field, Nested::Document(kind, params)))
            })
            .collect()
    }
}
