//! What every BSDF plugin's parameters offer: [`Plugin`] (the model it
//! builds) and its object-safe part [`Parameters`], through which
//! [`Material`] dispatches.

use std::sync::Arc;

use super::{Bsdf, Lookup, Material, Model};
use crate::scene::texture::Texture;

/// A BSDF plugin: its parameters, validated, as one `Material` variant
/// (parsed by the type's own `parse(&mut Params)`, which the registry
/// calls).
pub trait Plugin: Parameters {
    /// The reflection model the plugin builds, the payload of its `Bsdf`
    /// variant.
    type Model: Model;
}

/// The parameters' part of [`Plugin`] that [`Material`] dispatches to.
pub trait Parameters {
    /// The textures among the parameters (not the nested materials').
    fn textures(&self) -> Vec<&Texture>;

    /// The nested materials, in order.
    fn nested(&self) -> Vec<&Arc<Material>> {
        Vec::new()
    }

    /// Whether the material may be one side of a `twosided` one.
    fn may_be_a_side(&self) -> bool {
        true
    }

    /// The model with the textures valued by `lookup` (pbrt-v4's
    /// `GetBxDF`), reusing the precomputed tables of `template`, a BSDF
    /// built from the same parameters, when there is one. A rough plugin
    /// whose roughness is below what microfacets resolve builds its
    /// smooth sibling's model.
    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf;
}
