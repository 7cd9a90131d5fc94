//! The JSON scene document as serde types (`docs/scene-format.md` is the
//! user-facing description). These types mirror the file one to one; the
//! loader validates them and builds the [`Scene`](super::Scene).
//!
//! Objects are flat structs with a `type` field rather than serde-tagged
//! enums so that errors keep an exact field path and line/column (tagged enums
//! buffer their content and lose both). Fields that do not belong to the
//! declared `type` are rejected by the loader.

use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
use std::collections::BTreeMap;

use serde::de::{self, MapAccess, SeqAccess, Unexpected, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

pub use crate::color::RgbArray;
pub type Vec3 = [f64; 3];

/// Top level of a scene file.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDoc {
    /// Display name; defaults to the file stem.
    pub name: Option<String>,
    /// Free text for humans; ignored.
    pub description: Option<String>,
    #[serde(default)]
    pub materials: Vec<MaterialDoc>,
    pub shapes: Vec<ShapeDoc>,
    /// Point, spot and directional lights (`scene::emitter`), each a
    /// plugin document parsed there.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<serde_json::Map<String, serde_json::Value>>,
    pub environment: Option<EnvironmentDoc>,
    pub camera: CameraDoc,
    /// Camera rays pass through area emitters and see no environment.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub hide_emitters: bool,
    /// The longest path the scene is meant to be rendered with, in segments
    /// from the camera (1 = emitters seen directly): the depth of every
    /// request on the scene that names none. Default: the service's (16).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_depth: Option<u32>,
}

/// A material: its plugin `type` and that plugin's parameters, which
/// `scene::material` parses and validates (unknown ones are refused there,
/// naming the field).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MaterialDoc {
    pub id: String,
    #[serde(rename = "type")]
    pub kind: String,
    #[serde(flatten)]
    pub params: serde_json::Map<String, serde_json::Value>,
}

/// A shape's `type`: a plugin of the shape registry (`scene::shape`), by
/// its index there; (de)serialised there, as the plugin's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShapeKind(pub(crate) usize);

/// A shape: the family's generic fields, typed here, and its plugin's own
/// parameters ([`ShapeParam`]s by name), which the plugin's file
/// (`scene/shape/`) documents, reads and validates; the loader refuses the
/// names the plugin does not take.
///
/// (De)serialised as one flat JSON object by hand rather than with
/// `#[serde(flatten)]`, which would buffer every value (a large inline mesh
/// several times over) and lose the line and column of errors.
#[derive(Debug)]
pub struct ShapeDoc {
    pub kind: ShapeKind,
    /// Optional name for messages and tooling.
    pub id: Option<String>,
    /// Id of an entry of `materials`.
    pub material: String,
    pub to_world: Option<TransformDoc>,
    pub emitter: Option<EmitterDoc>,
    /// Turn the front side (and with it the emitting side) around.
    pub flip_normals: bool,
    /// A sensor on the shape (an irradiance meter).
    pub sensor: Option<SensorDoc>,
    /// The plugin's parameters, by name (ordered, so the document
    /// serialises, and the scene's digest hashes, the same either way).
    pub params: BTreeMap<String, ShapeParam>,
}

/// The generic fields of [`ShapeDoc`], in serialisation order.
const SHAPE_FIELDS: &[&str] = &[
    "type",
    "id",
    "material",
    "to_world",
    "emitter",
    "flip_normals",
    "sensor",
];

impl ShapeDoc {
    /// A document with only the required fields set.
    pub fn new(kind: ShapeKind, material: String) -> Self {
        Self {
            kind,
            id: None,
            material,
            to_world: None,
            emitter: None,
            flip_normals: false,
            sensor: None,
            params: BTreeMap::new(),
        }
    }
}

impl Serialize for ShapeDoc {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(None)?;
        map.serialize_entry("type", &self.kind)?;
        map.serialize_entry("id", &self.id)?;
        map.serialize_entry("material", &self.material)?;
        map.serialize_entry("to_world", &self.to_world)?;
        map.serialize_entry("emitter", &self.emitter)?;
        map.serialize_entry("flip_normals", &self.flip_normals)?;
        // Only when given: shapes without one keep their digests.
        if let Some(sensor) = &self.sensor {
            map.serialize_entry("sensor", sensor)?;
        }
        for (name, value) in &self.params {
            map.serialize_entry(name, value)?;
        }
        map.end()
    }
}

impl<'de> Deserialize<'de> for ShapeDoc {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct DocVisitor;
        impl<'de> Visitor<'de> for DocVisitor {
            type Value = ShapeDoc;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a shape object")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<ShapeDoc, A::Error> {
                let (mut kind, mut material) = (None, None);
                let mut doc = ShapeDoc::new(ShapeKind(0), String::new());
                let mut seen = Vec::new();
                while let Some(key) = map.next_key::<String>()? {
                    if seen.contains(&key) || doc.params.contains_key(&key) {
                        let name = SHAPE_FIELDS.iter().find(|f| **f == key);
                        return Err(match name {
                            Some(name) => de::Error::duplicate_field(name),
                            None => de::Error::custom(format!("duplicate field `{key}`")),
                        });
                    }
                    match key.as_str() {
                        "type" => kind = Some(map.next_value()?),
                        "id" => doc.id = map.next_value()?,
                        "material" => material = Some(map.next_value()?),
                        "to_world" => doc.to_world = map.next_value()?,
                        "emitter" => doc.emitter = map.next_value()?,
                        "flip_normals" => doc.flip_normals = map.next_value()?,
                        "sensor" => doc.sensor = map.next_value()?,
                        _ => {
                            let value = map.next_value()?;
                            doc.params.insert(key, value);
                            continue;
                        }
                    }
                    seen.push(key);
                }
                doc.kind = kind.ok_or_else(|| de::Error::missing_field("type"))?;
                doc.material = material.ok_or_else(|| de::Error::missing_field("material"))?;
                Ok(doc)
            }
        }
        deserializer.deserialize_map(DocVisitor)
    }
}

/// A sensor a shape carries: Mitsuba 3's `irradiancemeter`, the mean
/// irradiance over the shape's front side (`scene::meter`), which the
/// `irradiance` command reports when given no points.
#[derive(Debug, Serialize, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum SensorDoc {
    Irradiancemeter,
}

/// One parameter of a shape plugin as the document gives it, in the value
/// kinds JSON has; the plugin reads it into its own type (`scene::shape`'s
/// `ShapeFields`). A list of number lists is stored flat, so a large
/// inline mesh costs 8 bytes a number, as a typed one would.
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeParam {
    Bool(bool),
    Number(f64),
    Text(String),
    /// `[x, y, …]` (also the empty list).
    Numbers(Vec<f64>),
    /// `[[…], […], …]`: rows of `arity` numbers each, row-major.
    Rows {
        arity: usize,
        values: Vec<f64>,
    },
}

impl Serialize for ShapeParam {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            ShapeParam::Bool(b) => serializer.serialize_bool(*b),
            ShapeParam::Number(x) => serializer.serialize_f64(*x),
            ShapeParam::Text(t) => serializer.serialize_str(t),
            ShapeParam::Numbers(v) => v.serialize(serializer),
            ShapeParam::Rows { arity, values } => {
                serializer.collect_seq(values.chunks(*arity.max(&1)))
            }
        }
    }
}

impl<'de> Deserialize<'de> for ShapeParam {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_any(ParamVisitor)
    }
}

/// What the first entry of a list made it: numbers, or rows of so many.
#[derive(Clone, Copy, PartialEq)]
enum Entry {
    Number,
    Row(usize),
}

/// One entry of a list, appended to `values`; `expected` is what the
/// list's first entry was (`None` for the first).
struct EntrySeed<'v> {
    values: &'v mut Vec<f64>,
    expected: Option<Entry>,
}

impl<'de> de::DeserializeSeed<'de> for EntrySeed<'_> {
    type Value = Entry;
    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<Entry, D::Error> {
        deserializer.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for EntrySeed<'_> {
    type Value = Entry;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self.expected {
            None => f.write_str("a number or a list of numbers"),
            Some(Entry::Number) => f.write_str("a number, as the list's first entry"),
            Some(Entry::Row(n)) => write!(f, "a list of {n} numbers, as the list's first entry"),
        }
    }
    fn visit_f64<E: de::Error>(self, x: f64) -> Result<Entry, E> {
        if self.expected.is_some_and(|e| e != Entry::Number) {
            return Err(E::invalid_type(Unexpected::Float(x), &self));
        }
        self.values.push(x);
        Ok(Entry::Number)
    }
    fn visit_u64<E: de::Error>(self, x: u64) -> Result<Entry, E> {
        self.visit_f64(x as f64)
    }
    fn visit_i64<E: de::Error>(self, x: i64) -> Result<Entry, E> {
        self.visit_f64(x as f64)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Entry, A::Error> {
        if self.expected == Some(Entry::Number) {
            return Err(de::Error::invalid_type(Unexpected::Seq, &self));
        }
        let mut n = 0;
        while let Some(x) = seq.next_element::<f64>()? {
            self.values.push(x);
            n += 1;
        }
        match self.expected {
            Some(Entry::Row(want)) if want != n => Err(de::Error::invalid_length(n, &self)),
            _ => Ok(Entry::Row(n)),
        }
    }
}

struct ParamVisitor;

impl<'de> Visitor<'de> for ParamVisitor {
    type Value = ShapeParam;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a number, a string, a boolean or a list of numbers or of number lists")
    }
    fn visit_bool<E: de::Error>(self, b: bool) -> Result<ShapeParam, E> {
        Ok(ShapeParam::Bool(b))
    }
    fn visit_f64<E: de::Error>(self, x: f64) -> Result<ShapeParam, E> {
        Ok(ShapeParam::Number(x))
    }
    fn visit_u64<E: de::Error>(self, x: u64) -> Result<ShapeParam, E> {
        Ok(ShapeParam::Number(x as f64))
    }
    fn visit_i64<E: de::Error>(self, x: i64) -> Result<ShapeParam, E> {
        Ok(ShapeParam::Number(x as f64))
    }
    fn visit_str<E: de::Error>(self, s: &str) -> Result<ShapeParam, E> {
        Ok(ShapeParam::Text(s.to_owned()))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<ShapeParam, A::Error> {
        let mut values = Vec::new();
        let first = seq.next_element_seed(EntrySeed {
            values: &mut values,
            expected: None,
        })?;
        let Some(first) = first else {
            return Ok(ShapeParam::Numbers(values));
        };
        while seq
            .next_element_seed(EntrySeed {
                values: &mut values,
                expected: Some(first),
            })?
            .is_some()
        {}
        Ok(match first {
            Entry::Number => ShapeParam::Numbers(values),
            Entry::Row(arity) => ShapeParam::Rows { arity, values },
        })
    }
}

#[derive(Debug, Serialize, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum EmitterKind {
    Area,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmitterDoc {
    #[serde(rename = "type")]
    pub kind: EmitterKind,
    /// Emitted radiance, W/(m²·sr) per channel, from the front side: a
    /// colour, or a texture document (`texture.rs`) over the shape's
    /// texture coordinates.
    pub radiance: serde_json::Value,
}

#[derive(Debug, Serialize, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum EnvironmentKind {
    Constant,
    Envmap,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDoc {
    #[serde(rename = "type")]
    pub kind: EnvironmentKind,
    /// constant: radiance from every direction.
    pub radiance: Option<RgbArray>,
    /// envmap: lat-long EXR, relative to the scene file.
    pub filename: Option<String>,
    /// envmap: multiplier on the texels (default 1).
    pub scale: Option<f64>,
    /// envmap: rotation from map to world.
    pub to_world: Option<TransformDoc>,
}

#[derive(Debug, Serialize, Deserialize, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum CameraKind {
    #[default]
    Perspective,
    /// A perspective camera with a thin lens: depth of field.
    Thinlens,
    /// Parallel rays along the camera's +z, leaving its xy plane: the image
    /// spans x ∈ [−1, 1] and y ∈ [−1/aspect, 1/aspect] of camera space,
    /// which `to_world`'s scale sizes (Mitsuba 3's `orthographic`).
    Orthographic,
}

#[derive(Debug, Serialize, Deserialize, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum FovAxis {
    #[default]
    X,
    Y,
    Smaller,
    Larger,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDoc {
    #[serde(rename = "type", default)]
    pub kind: CameraKind,
    /// Full field of view in degrees along `fov_axis` (perspective and
    /// thinlens cameras; an orthographic camera has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov: Option<f64>,
    #[serde(default)]
    pub fov_axis: FovAxis,
    pub width: u32,
    pub height: u32,
    /// Camera to world; the camera looks along local +z with +y up.
    pub to_world: Option<TransformDoc>,
    pub origin: Option<Vec3>,
    pub target: Option<Vec3>,
    pub up: Option<Vec3>,
    /// thinlens: the aperture's radius, scene units (required).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture_radius: Option<f64>,
    /// thinlens: distance from the lens to the plane in focus, scene units
    /// (default 10⁴, Mitsuba's far clip).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focus_distance: Option<f64>,
    /// The film's reconstruction filter (default `box`: each pixel's mean
    /// radiance); see `scene::pixel_filter`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub filter: Option<FilterDoc>,
}

/// A reconstruction filter, Mitsuba 3's names and defaults; widths in pixels.
#[derive(Debug, Serialize, Deserialize, Clone, Copy, PartialEq, Default)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum FilterDoc {
    #[default]
    Box,
    /// Cut off at 4 `stddev` (default 0.5).
    Gaussian { stddev: Option<f64> },
    /// `radius` default 1.
    Tent { radius: Option<f64> },
}

/// One step of a `to_world` transform.
#[derive(Debug, Serialize, Deserialize, Clone, PartialEq)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum TransformOp {
    /// Row-major 4×4 affine matrix (last row 0 0 0 1).
    Matrix([[f64; 4]; 4]),
    Translate(Vec3),
    /// Rotation by `angle` degrees, counter-clockwise looking down `axis`.
    Rotate {
        axis: Vec3,
        angle: f64,
    },
    /// Per-axis scale factors.
    Scale(Vec3),
    /// Frame at `origin` whose +z looks at `target` with +y towards `up`.
    LookAt {
        origin: Vec3,
        target: Vec3,
        up: Vec3,
    },
}

/// A `to_world` value: one operation object or a list applied in order
/// (later operations apply after earlier ones, as in Mitsuba). Serialises
/// as the list of operations.
#[derive(Debug, Serialize, Clone, PartialEq)]
pub struct TransformDoc {
    pub ops: Vec<TransformOp>,
    /// True when written as a single object rather than a list; only used to
    /// print field paths the way the user wrote them.
    #[serde(skip)]
    pub single: bool,
}

impl<'de> Deserialize<'de> for TransformDoc {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct OneOrMany;
        impl<'de> Visitor<'de> for OneOrMany {
            type Value = TransformDoc;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(
                    "a transform operation such as {\"translate\": [x, y, z]} or a list of them",
                )
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<TransformDoc, A::Error> {
                let ops = Vec::deserialize(SeqAccessDeserializer::new(seq))?;
                Ok(TransformDoc { ops, single: false })
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<TransformDoc, A::Error> {
                let op = TransformOp::deserialize(MapAccessDeserializer::new(map))?;
                Ok(TransformDoc {
                    ops: vec![op],
                    single: true,
                })
            }
        }
        deserializer.deserialize_any(OneOrMany)
    }
}

impl TransformDoc {
    /// Field path of operation `i` below `base` (e.g. `shapes[2].to_world[1]`).
    pub fn op_field(&self, base: &str, i: usize) -> String {
        if self.single {
            base.to_string()
        } else {
            format!("{base}[{i}]")
        }
    }
}
