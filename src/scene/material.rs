//! Surface materials: the BSDF plugins, one file each under
//! `scene/material/` (Mitsuba 3's plugin names), each holding its
//! parameters' docs, their parsing and validation through `Params`, its
//! reflection model (implementing [`Model`]: `eval`, `pdf`, `sample` in the
//! local frame, z = normal) and its build step from the parameters to the
//! model with the textures valued at a point (`build`, pbrt-v4's
//! `GetBxDF`), its tests beside it. The registry is one list, the
//! `plugins!` invocation below: each line generates the plugin's `mod`,
//! its variants of [`Material`] (parameters) and [`Bsdf`] (model), its
//! entry in the name → parser table and its dispatch arms, so a plugin is
//! registered whole or not at all.
//!
//! A material document is `{"id": …, "type": PLUGIN, PARAMETER: value, …}`
//! with Mitsuba 3's plugin and parameter names, so a Mitsuba `<bsdf>`
//! translates into one by copying its properties. Parameters take:
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

mod bsdf;
pub mod ior;
pub mod metals;
#[cfg(test)]
mod mitsuba_agreement;
mod optical_params;
mod perturbed;
pub use optical_params::Interface;
mod plugin;

use std::sync::Arc;

use super::bitmap::Bitmaps;
use super::error::SceneError;
use super::format::MaterialDoc;
use super::params::Nested;
pub(crate) use super::params::Params;
use super::texture::Texture;
use crate::optics::microfacet::{MIN_ALPHA, Microfacet, MicrofacetKind};
pub use bsdf::{BsdfFlags, LobeSample, Lookup, Model, SurfacePoint, flip, reflect};
pub use plugin::Plugin;

/// Most plugins one material may expand to, counting a shared nested
/// material each time it is used: shading walks the whole tree at every
/// surface point. Published scenes nest a few (a blend of two-sided
/// coatings); `blendbsdf` doubling a shared material ten times would make
/// 2047.
pub const MAX_MATERIAL_NODES: usize = 64;

/// Materials declared so far in a scene, by id, for nested references.
pub(crate) type Declared = std::collections::HashMap<String, std::sync::Arc<Material>>;

/// Sampling density (sr⁻¹) above which a lobe counts as sharp
/// ([`Material::makes_caustics`]): GGX of roughness α has its peak near
/// `1/(4π α²)` at normal incidence, so this is α ≈ 0.2 (Phong exponents
/// near 12 if Phong were path traced; the cache integrates Phong lobes by
/// BMC, which sees their shape).
pub const SHARP_LOBE_DENSITY: f64 = 2.0;

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

impl Roughness {
    /// `(alpha_u, alpha_v)` at texture coordinates `uv`.
    pub fn at(&self, uv: glam::DVec2) -> (f64, f64) {
        match &self.textures {
            Some(t) => (t[0].eval_scalar(uv), t[1].eval_scalar(uv)),
            None => (self.alpha_u, self.alpha_v),
        }
    }

    /// The slope textures, if the roughness varies over the surface.
    pub fn textures(&self) -> impl Iterator<Item = &Texture> {
        self.textures.iter().flat_map(|t| t.iter())
    }

    /// The distribution with the slopes valued by `lookup`, or `None` when
    /// they are below what the microfacet models resolve (the plugin then
    /// builds its smooth model instead).
    pub fn microfacet(&self, lookup: Lookup) -> Option<Microfacet> {
        let kind = match self.distribution {
            Distribution::Beckmann => MicrofacetKind::Beckmann,
            Distribution::Ggx => MicrofacetKind::Ggx,
        };
        match (lookup, &self.textures) {
            // A roughness map's texels below the smallest roughness stay
            // rough (the material is rough wherever it is, as its mean says).
            (Lookup::At(p), Some(_)) => {
                let (u, v) = self.at(p.uv);
                Microfacet::new(kind, u.max(MIN_ALPHA), v.max(MIN_ALPHA))
            }
            _ => Microfacet::new(kind, self.alpha_u, self.alpha_v),
        }
    }
}

/// The BSDF plugins: `Variant(file::Parameters) = "name"`, one line each.
/// For each line the macro declares `pub mod file;` (the plugin's file),
/// the variant `Material::Variant(Parameters)` and the variant
/// `Bsdf::Variant(<Parameters as Plugin>::Model)`, the parser of `"name"`
/// and the arms dispatching to the plugin's [`Plugin`] and [`Model`]
/// implementations.
macro_rules! plugins {
    ($($variant:ident($file:ident::$plugin:ident) = $name:literal,)*) => {
        $(pub mod $file;)*

        /// A surface's BSDF plugin with its parameters validated (each
        /// plugin's file documents its fields).
        #[derive(Clone, Debug, PartialEq)]
        pub enum Material {
            $($variant($file::$plugin),)*
        }

        /// A surface's BSDF: the model of a [`Material`] with its textures
        /// valued (`Parameters::build`); see `bsdf.rs`.
        #[derive(Clone, Debug, PartialEq)]
        pub enum Bsdf {
            $($variant(<$file::$plugin as Plugin>::Model),)*
        }

        /// Every material plugin, by its `type`.
        const PLUGINS: &[(&str, Parse)] = &[
            $(($name, |params| Ok(Material::$variant($file::$plugin::parse(params)?))),)*
        ];

        impl Material {
            /// The plugin's parameters, for dispatch.
            fn plugin(&self) -> &dyn Parameters {
                match self {
                    $(Material::$variant(p) => p,)*
                }
            }
        }

        impl Bsdf {
            /// The plugin's model, for dispatch.
            fn model(&self) -> &dyn Model {
                match self {
                    $(Bsdf::$variant(m) => m,)*
                }
            }
        }
    };
}

plugins! {
    Diffuse(diffuse::DiffuseMaterial) = "diffuse",
    Glossy(glossy::GlossyMaterial) = "glossy",
    Conductor(conductor::ConductorMaterial) = "conductor",
    RoughConductor(rough_conductor::RoughConductorMaterial) = "roughconductor",
    Dielectric(dielectric::DielectricMaterial) = "dielectric",
    ThinDielectric(thin_dielectric::ThinDielectricMaterial) = "thindielectric",
    RoughDielectric(rough_dielectric::RoughDielectricMaterial) = "roughdielectric",
    Plastic(plastic::PlasticMaterial) = "plastic",
    RoughPlastic(rough_plastic::RoughPlasticMaterial) = "roughplastic",
    TwoSided(twosided::TwoSidedMaterial) = "twosided",
    Blend(blend::BlendMaterial) = "blendbsdf",
    Mask(mask::MaskMaterial) = "mask",
    BumpMap(bumpmap::BumpMapMaterial) = "bumpmap",
    NormalMap(normalmap::NormalMapMaterial) = "normalmap",
    Principled(principled::PrincipledMaterial) = "principled",
    PrincipledThin(principled_thin::PrincipledThinMaterial) = "principledthin",
}

use plugin::Parameters;

/// A plugin's parser: its parameters to a material.
type Parse = fn(&mut Params) -> Result<Material, SceneError>;

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
        for inner in self.plugin().nested() {
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
        let plugin = self.plugin();
        let mut all = plugin.textures();
        for inner in plugin.nested() {
            all.extend(inner.textures());
        }
        all
    }

    /// Whether the material may be one side of a `twosided` one (a
    /// dielectric is the same from both sides, a two-sided one is already).
    pub(crate) fn may_be_a_side(&self) -> bool {
        self.plugin().may_be_a_side()
    }

    /// The material's BSDF with its textures valued by `lookup`, reusing
    /// the precomputations of `template` (a BSDF of the same material).
    pub(crate) fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        self.plugin().build(lookup, template)
    }

    /// Whether the material images light sources sharply enough to make
    /// caustics that irradiance records cannot sample: a Dirac delta
    /// (mirror, glass), or a lobe other than Phong's whose density at
    /// normal incidence peaks above [`SHARP_LOBE_DENSITY`] (the textures at
    /// their means). Probed by the lobe's own sampling, so it holds for
    /// every plugin.
    pub fn makes_caustics(&self) -> bool {
        let bsdf = self.build(Lookup::Mean, None);
        let flags = bsdf.flags();
        if flags.delta {
            return true;
        }
        if !flags.glossy || bsdf.phong().is_some() {
            return false;
        }
        let wo = glam::DVec3::Z;
        // A fixed 16 × 16 grid of lobe samples: deterministic, and dense
        // enough to land near a peak whose half-width is α.
        (0..256).any(|i| {
            let u = [
                (f64::from(i % 16) + 0.5) / 16.0,
                (f64::from(i / 16) + 0.5) / 16.0,
            ];
            (0..4).any(|l| {
                bsdf.sample(wo, (f64::from(l) + 0.5) / 4.0, u)
                    .is_some_and(|s| bsdf.pdf(wo, s.wi) > SHARP_LOBE_DENSITY)
            })
        })
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
    pub(crate) fn nested(params: &mut Params) -> Result<Vec<(String, Arc<Material>)>, SceneError> {
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
                (Nested::Reference(_), None) => {
                    let grey = serde_json::json!({"reflectance": 0.5});
                    let grey = grey.as_object().expect("an object").clone();
                    Arc::new(Self::parse(
                        "diffuse",
                        &mut Params::new(&field, grey),
                        &field,
                    )?)
                }
            };
            out.push((field, material));
        }
        Ok(out)
    }

    /// The one material nested under `bsdf` in a `plugin` that wraps one
    /// (`mask`, `bumpmap`, `normalmap`).
    pub(crate) fn one_nested(
        params: &mut Params,
        plugin: &str,
    ) -> Result<Arc<Material>, SceneError> {
        let nested: Vec<_> = Self::nested(params)?.into_iter().map(|(_, m)| m).collect();
        match <[_; 1]>::try_from(nested) {
            Ok([bsdf]) => Ok(bsdf),
            Err(_) => Err(params.invalid(
                "bsdf",
                format!("a {plugin} needs exactly one nested material"),
            )),
        }
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
