//! Per-scene light-transport state: the scene, its light-selection tables
//! and one BSDF per material. Built once per scene and shared between
//! threads (and requests); the estimators in `path` and `irradiance` are
//! methods on it.

use std::borrow::Cow;
use std::sync::Arc;

use super::environment_prior::EnvironmentPrior;
use super::environment_sampling::environment_relative_variance;
use super::lights::LightSampler;
use crate::scene::material::Bsdf;
use crate::scene::{Material, Scene, SurfaceHit};

/// Per-scene state for light transport: the scene, its light-selection
/// tables and one BSDF per material. Build once per scene and share.
pub struct Transport {
    scene: Arc<Scene>,
    lights: LightSampler,
    /// `bsdfs[i]` reflects like `scene.materials[i]` (with its textures
    /// at their means, see [`Transport::bsdf_at`]).
    bsdfs: Vec<Bsdf>,
    /// `textured[i]`: material `i` varies over its surfaces.
    textured: Vec<bool>,
    /// The unoccluded environment as a prior mean; `None` without an environment.
    environment_prior: Option<EnvironmentPrior>,
    /// `Var L / (E L)²` of the environment, computed once (every `auto`
    /// request asks); `None` without an environment.
    environment_relative_variance: Option<f64>,
}

impl Transport {
    pub fn new(scene: Arc<Scene>) -> Self {
        let lights = LightSampler::new(&scene);
        let bsdfs = scene.materials.iter().map(Bsdf::from).collect();
        let textured = scene.materials.iter().map(Material::is_textured).collect();
        let environment_prior = scene.environment.as_ref().map(EnvironmentPrior::new);
        let environment_relative_variance = scene
            .environment
            .as_ref()
            .map(environment_relative_variance);
        Self {
            scene,
            lights,
            bsdfs,
            textured,
            environment_prior,
            environment_relative_variance,
        }
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub(crate) fn lights(&self) -> &LightSampler {
        &self.lights
    }

    /// The environment prior mean (docs/math.md §10.4), if the scene has an environment.
    pub fn environment_prior(&self) -> Option<&EnvironmentPrior> {
        self.environment_prior.as_ref()
    }

    /// `Var L / (E L)²` of the environment's radiance over the sphere
    /// (computed once at load), if the scene has an environment.
    pub fn environment_relative_variance(&self) -> Option<f64> {
        self.environment_relative_variance
    }

    /// Reflection model of material `material` with its textures at their
    /// means (`None` for an unknown index); [`Self::bsdf_at`] is the one at
    /// a surface point.
    pub fn bsdf(&self, material: usize) -> Option<&Bsdf> {
        self.bsdfs.get(material)
    }

    /// The BSDF at `hit`: its material's, with textures looked up at the
    /// hit's texture coordinates (`None` for an unknown material).
    pub fn bsdf_at(&self, hit: &SurfaceHit) -> Option<Cow<'_, Bsdf>> {
        let template = self.bsdfs.get(hit.material)?;
        if !self.textured[hit.material] {
            return Some(Cow::Borrowed(template));
        }
        let material = &self.scene.materials[hit.material];
        Some(Cow::Owned(Bsdf::textured(material, hit, template)))
    }
}
