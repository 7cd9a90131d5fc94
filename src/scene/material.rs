//! Surface materials as data: what a scene file says about a surface's
//! BSDF, validated once here (evaluation and sampling live with the light
//! transport, `render::bsdf`).
//!
//! A material document is `{"id": …, "type": PLUGIN, PARAMETER: value, …}`
//! with Mitsuba 3's plugin and parameter names, so a Mitsuba `<bsdf>`
//! translates into one by copying its properties. Each plugin parses its
//! own parameters in its own file below (`diffuse.rs`, `conductor.rs`, …),
//! opening with their docs; [`PLUGINS`] is the registry. Parameters take:
//! - colours: a number (grey) or `[r, g, b]`, linear RGB; the reflectances
//!   and transmittances Mitsuba textures also take a texture document
//!   ([`Texture`], `scene::texture`);
//! - indices of refraction: a number or a named medium ([`ior`]);
//! - metals: `eta` and `k` as colours, or `material`, a named metal ([`metals`]);
//! - nested materials (`bsdf` of `twosided`, `blendbsdf`, `mask`): a
//!   material document, or the `id` of a material declared before this one,
//!   which is shared, not copied. Sharing lets a few lines describe a tree
//!   of any size, which every shading point would walk, so a material may
//!   expand to at most [`MAX_MATERIAL_NODES`] plugins.

mod blend;
mod conductor;
mod dielectric;
mod diffuse;
mod glossy;
pub mod ior;
mod mask;
pub mod metals;
mod optics;
mod plastic;
mod twosided;

use std::sync::Arc;

use super::bitmap::Bitmaps;
use super::error::SceneError;
use super::format::MaterialDoc;
use super::params::Nested;
pub(crate) use super::params::Params;
use super::texture::Texture;

/// Most plugins one material may expand to, counting a shared nested
/// material each time it is used: shading walks the whole tree at every
/// surface point. Published scenes nest a few (a blend of two-sided
/// coatings); `blendbsdf` doubling a shared material ten times would make
/// 2047.
pub const MAX_MATERIAL_NODES: usize = 64;

/// Materials declared so far in a scene, by id, for nested references.
pub(crate) type Declared = std::collections::HashMap<String, std::sync::Arc<Material>>;

/// Largest accepted Phong exponent; beyond it the lobe is a mirror for all
/// practical purposes and sampling it in f64 loses precision.
pub const MAX_PHONG_EXPONENT: f64 = 1e6;

/// A linear RGB triple.
pub use crate::color::RgbArray;

/// Microfacet normal distributions (Walter et al. 2007).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Distribution {
    Beckmann,
    Ggx,
}

/// A microfacet surface's roughness: distribution and the RMS slopes
/// along the tangent (`alpha_u`) and bitangent (`alpha_v`), both > 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Roughness {
    pub distribution: Distribution,
    /// The slopes where no surface point is at hand: the constants given,
    /// or the textures' means.
    pub alpha_u: f64,
    pub alpha_v: f64,
    /// `[alpha_u, alpha_v]` as textures (scalar lookups, Mitsuba's `eval_1`)
    /// when either varies over the surface.
    pub textures: Option<Box<[Texture; 2]>>,
}

/// The roughness textures of `roughness`, if any.
fn roughness_textures(roughness: &Option<Roughness>) -> impl Iterator<Item = &Texture> {
    roughness
        .iter()
        .flat_map(|r| r.textures.iter().flat_map(|t| t.iter()))
}

impl Roughness {
    /// `(alpha_u, alpha_v)` at texture coordinates `uv`.
    pub fn at(&self, uv: glam::DVec2) -> (f64, f64) {
        match &self.textures {
            Some(t) => (t[0].eval_scalar(uv), t[1].eval_scalar(uv)),
            None => (self.alpha_u, self.alpha_v),
        }
    }
}

/// A surface's BSDF with its parameters validated (see each plugin's file
/// for the meaning of its fields).
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflector; `reflectance` is the albedo in [0, 1] per channel.
    Diffuse { reflectance: Texture },
    /// Diffuse albedo plus a normalised Phong lobe with albedo `specular`
    /// (at normal incidence) and exponent `exponent ≥ 0`.
    Glossy {
        diffuse: RgbArray,
        specular: RgbArray,
        exponent: f64,
    },
    /// A metal: smooth (`roughness: None`, a mirror) or microfacet.
    Conductor {
        eta: RgbArray,
        k: RgbArray,
        specular_reflectance: Texture,
        roughness: Option<Roughness>,
    },
    /// An interface between dielectrics of relative index `eta =
    /// int_ior / ext_ior`: smooth, microfacet, or a thin slab.
    Dielectric {
        eta: f64,
        specular_reflectance: Texture,
        specular_transmittance: Texture,
        roughness: Option<Roughness>,
        thin: bool,
    },
    /// A diffuse base under a dielectric coating of relative index `eta`,
    /// smooth (`roughness: None`) or microfacet (isotropic).
    Plastic {
        diffuse_reflectance: Texture,
        specular_reflectance: Texture,
        eta: f64,
        nonlinear: bool,
        roughness: Option<Roughness>,
    },
    /// `front` on the side the normal points to, `back` on the other.
    TwoSided {
        front: Arc<Material>,
        back: Arc<Material>,
    },
    /// `(1 − w) f₀ + w f₁` with `w` the luminance of `weight`.
    Blend {
        weight: Texture,
        bsdfs: [Arc<Material>; 2],
    },
    /// `bsdf` where the surface is present (probability: the luminance of
    /// `opacity`), straight through elsewhere.
    Mask {
        opacity: Texture,
        bsdf: Arc<Material>,
    },
}

/// A plugin's parser: its parameters to a material.
type Parse = fn(&mut Params) -> Result<Material, SceneError>;

/// Every material plugin, by its `type`: one line per plugin.
const PLUGINS: &[(&str, Parse)] = &[
    ("diffuse", diffuse::parse),
    ("glossy", glossy::parse),
    ("conductor", conductor::parse_smooth),
    ("roughconductor", conductor::parse_rough),
    ("dielectric", dielectric::parse_smooth),
    ("thindielectric", dielectric::parse_thin),
    ("roughdielectric", dielectric::parse_rough),
    ("plastic", plastic::parse_smooth),
    ("roughplastic", plastic::parse_rough),
    ("twosided", twosided::parse),
    ("blendbsdf", blend::parse),
    ("mask", mask::parse),
];

/// The plugin names [`Material::from_doc`] accepts, for messages and docs.
pub fn plugin_names() -> Vec<&'static str> {
    PLUGINS.iter().map(|(name, _)| *name).collect()
}

impl Material {
    /// Validates one `materials[i]` entry; `field` is its path. Bitmap
    /// textures are read through `bitmaps`; nested references name the
    /// materials `declared` before it.
    pub(crate) fn from_doc(
        doc: &MaterialDoc,
        field: &str,
        bitmaps: &Bitmaps,
        declared: &Declared,
    ) -> Result<Self, SceneError> {
        let mut params = Params::new(field, doc.params.clone())
            .with_bitmaps(bitmaps)
            .with_declared(declared);
        let material = Self::parse(&doc.kind, &mut params, field)?;
        params.finish()?;
        let nodes = material.nodes_up_to(MAX_MATERIAL_NODES + 1);
        if nodes > MAX_MATERIAL_NODES {
            return Err(SceneError::invalid(
                format!("{field}.bsdf"),
                format!(
                    "the material expands to more than {MAX_MATERIAL_NODES} plugins (MAX_MATERIAL_NODES), counting each use of a shared one"
                ),
            ));
        }
        Ok(material)
    }

    /// The plugins the material expands to (itself and, recursively, each
    /// use of a nested one), counted up to `cap` and no further, so that
    /// counting costs at most `cap` steps whatever the sharing.
    pub fn nodes_up_to(&self, cap: usize) -> usize {
        let mut count = 1;
        let nested: &[&Arc<Material>] = match self {
            Material::TwoSided { front, back } => &[front, back],
            Material::Blend { bsdfs, .. } => &[&bsdfs[0], &bsdfs[1]],
            Material::Mask { bsdf, .. } => &[bsdf],
            _ => &[],
        };
        for inner in nested {
            if count >= cap {
                break;
            }
            count += inner.nodes_up_to(cap - count);
        }
        count.min(cap)
    }

    /// The parameters of a `kind` document that its plugin does not take,
    /// when the others parse (none otherwise: the loader then reports the
    /// error), so that a translator can drop them with a warning.
    pub(crate) fn unknown_parameters(
        kind: &str,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Vec<String> {
        let mut params = Params::new("", params.clone());
        match Self::parse(kind, &mut params, "") {
            Ok(_) => params.remaining(),
            Err(_) => Vec::new(),
        }
    }

    /// The textures of the material's parameters (nested materials' too).
    pub fn textures(&self) -> Vec<&Texture> {
        match self {
            Material::Diffuse { reflectance } => vec![reflectance],
            Material::Glossy { .. } => Vec::new(),
            Material::Conductor {
                specular_reflectance,
                roughness,
                ..
            } => [specular_reflectance]
                .into_iter()
                .chain(roughness_textures(roughness))
                .collect(),
            Material::Dielectric {
                specular_reflectance,
                specular_transmittance,
                roughness,
                ..
            } => [specular_reflectance, specular_transmittance]
                .into_iter()
                .chain(roughness_textures(roughness))
                .collect(),
            Material::Plastic {
                diffuse_reflectance,
                specular_reflectance,
                ..
            } => vec![diffuse_reflectance, specular_reflectance],
            Material::TwoSided { front, back } => {
                let mut all = front.textures();
                all.extend(back.textures());
                all
            }
            Material::Blend { weight, bsdfs } => {
                let mut all = vec![weight];
                all.extend(bsdfs[0].textures());
                all.extend(bsdfs[1].textures());
                all
            }
            Material::Mask { opacity, bsdf } => {
                let mut all = vec![opacity];
                all.extend(bsdf.textures());
                all
            }
        }
    }

    /// True if a parameter varies over the surface (a texture).
    pub fn is_textured(&self) -> bool {
        self.textures().iter().any(|t| t.constant().is_none())
    }

    /// The parameters of a `kind` document that hold a texture document
    /// where the plugin takes a constant (a translator may replace them by
    /// the texture's mean): found by parsing, each such error naming one.
    pub(crate) fn constant_parameters_given_textures(
        kind: &str,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Vec<String> {
        let mut params = params.clone();
        let mut found = Vec::new();
        loop {
            let Err(e) = Self::parse(kind, &mut Params::new("", params.clone()), "") else {
                return found;
            };
            let name = e.field().and_then(|f| f.strip_prefix('.'));
            let Some(name) = name.filter(|n| params.get(*n).is_some_and(|v| v.is_object())) else {
                return found;
            };
            if found.iter().any(|f| f == name) {
                return found;
            }
            // A texture of plain grey where the given one failed: if that
            // parses, the parameter takes textures and what failed is the
            // texture's values (a colour above 1), which is no case here.
            let texture = serde_json::json!({"type": "checkerboard", "color0": 0.5, "color1": 0.5});
            if Self::accepts(kind, &params, name, texture) {
                return found;
            }
            found.push(name.to_string());
            params.insert(name.to_string(), serde_json::Value::from(0.5));
        }
    }

    /// Whether a `kind` document `params` with `value` as parameter `name`
    /// parses without an error about `name` (name-only: no file is read).
    pub(crate) fn accepts(
        kind: &str,
        params: &serde_json::Map<String, serde_json::Value>,
        name: &str,
        value: serde_json::Value,
    ) -> bool {
        let mut params = params.clone();
        params.insert(name.to_string(), value);
        match Self::parse(kind, &mut Params::new("", params), "") {
            Err(e) => e.field().and_then(|f| f.strip_prefix('.')) != Some(name),
            Ok(_) => true,
        }
    }

    /// The materials nested under `bsdf` (one object or a list), each with
    /// its field path.
    fn nested(params: &mut Params) -> Result<Vec<(String, Arc<Material>)>, SceneError> {
        let mut out = Vec::new();
        let declared = params.declared::<Declared>();
        for (field, nested) in params.nested("bsdf")? {
            let material = match (nested, declared) {
                (Nested::Document(kind, mut inner), _) => {
                    let material = Self::parse(&kind, &mut inner, &field)?;
                    inner.finish()?;
                    Arc::new(material)
                }
                (Nested::Reference(id), Some(declared)) => {
                    declared.get(&id).cloned().ok_or_else(|| {
                        SceneError::invalid(
                            &field,
                            format!("no material {id:?} is declared before this one"),
                        )
                    })?
                }
                // Only the parameters' names are wanted: any material
                // stands in for the one named.
                (Nested::Reference(_), None) => Arc::new(Material::Diffuse {
                    reflectance: Texture::Constant([0.5; 3]),
                }),
            };
            out.push((field, material));
        }
        Ok(out)
    }

    /// The material of plugin `kind` from `params` (a nested BSDF's too).
    fn parse(kind: &str, params: &mut Params, field: &str) -> Result<Self, SceneError> {
        let Some((_, parse)) = PLUGINS.iter().find(|(name, _)| *name == kind) else {
            return Err(SceneError::invalid(
                format!("{field}.type"),
                format!(
                    "unknown material type {kind:?} (known: {})",
                    plugin_names().join(", ")
                ),
            ));
        };
        parse(params)
    }
}

#[cfg(test)]
mod tests;
