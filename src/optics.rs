//! The optics the reflection models are made of, below the scene: Fresnel
//! reflectance at smooth interfaces, microfacet distributions, and warps
//! from the unit square to directions with their densities. Pure math
//! with no scene in it, so a BSDF plugin of `scene::material` holds its
//! parameters and its model in one file. Directions are unit vectors in a
//! **local frame** (z = the surface normal) unless a function says
//! otherwise.

#[cfg(test)]
pub(crate) mod chi_square;
pub mod fresnel;
pub mod microfacet;
#[doc(hidden)]
pub mod warp;
