//! The JSON scene document as serde types (`docs/scene-format.md` is the
//! user-facing description). These types mirror the file one to one; the
//! loader validates them and builds the [`Scene`](super::Scene).
//!
//! Objects are flat structs with a `type` field rather than serde-tagged
//! enums so that errors keep an exact field path and line/column (tagged enums
//! buffer their content and lose both). Fields that do not belong to the
//! declared `type` are rejected by the loader.

use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
use serde::de::{MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};

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

/// A shape: the family's generic fields, then every plugin's own ones,
/// each optional here; the plugin's file (`scene/shape/`) documents and
/// validates those it takes, the loader refuses the others.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeDoc {
    #[serde(rename = "type")]
    pub kind: ShapeKind,
    /// Optional name for messages and tooling.
    pub id: Option<String>,
    /// Id of an entry of `materials`.
    pub material: String,
    pub to_world: Option<TransformDoc>,
    pub emitter: Option<EmitterDoc>,
    /// Turn the front side (and with it the emitting side) around.
    #[serde(default)]
    pub flip_normals: bool,
    /// `sphere`.
    pub center: Option<Vec3>,
    /// `sphere`.
    pub radius: Option<f64>,
    /// Mesh-file plugins (`obj`, `ply`, `serialized`).
    pub filename: Option<String>,
    /// `triangles`.
    pub positions: Option<Vec<Vec3>>,
    /// `triangles`.
    pub indices: Option<Vec<[u64; 3]>>,
    /// `triangles`.
    pub normals: Option<Vec<Vec3>>,
    /// `triangles`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uvs: Option<Vec<[f64; 2]>>,
    /// Mesh plugins (`obj`, `ply`, `serialized`, `triangles`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flip_tex_coords: Option<bool>,
    /// Mesh-file plugins.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub face_normals: Option<bool>,
    /// `serialized`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shape_index: Option<u32>,
}

impl ShapeDoc {
    /// The plugins' own fields by name, whether each is given, in the
    /// order the loader checks them.
    pub fn kind_fields(&self) -> [(&'static str, bool); 10] {
        [
            ("center", self.center.is_some()),
            ("radius", self.radius.is_some()),
            ("positions", self.positions.is_some()),
            ("indices", self.indices.is_some()),
            ("normals", self.normals.is_some()),
            ("uvs", self.uvs.is_some()),
            ("filename", self.filename.is_some()),
            ("face_normals", self.face_normals.is_some()),
            ("flip_tex_coords", self.flip_tex_coords.is_some()),
            ("shape_index", self.shape_index.is_some()),
        ]
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
    /// Full field of view in degrees along `fov_axis`.
    pub fov: f64,
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
