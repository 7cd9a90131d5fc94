//! Per-scene light-transport state: the scene, its light-selection tables
//! and one BSDF per material. Built once per scene and shared between
//! threads (and requests); the estimators in `path` and `irradiance` are
//! methods on it.

use std::sync::Arc;

use super::bsdf::Bsdf;
use super::lights::LightSampler;
use crate::scene::Scene;

/// Per-scene state for light transport: the scene, its light-selection
/// tables and one BSDF per material. Build once per scene and share.
pub struct Transport {
    scene: Arc<Scene>,
    lights: LightSampler,
    /// `bsdfs[i]` reflects like `scene.materials[i]`.
    bsdfs: Vec<Bsdf>,
}

impl Transport {
    pub fn new(scene: Arc<Scene>) -> Self {
        let lights = LightSampler::new(&scene);
        let bsdfs = scene.materials.iter().map(Bsdf::from).collect();
        Self {
            scene,
            lights,
            bsdfs,
        }
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn lights(&self) -> &LightSampler {
        &self.lights
    }

    /// Reflection model of material `material` (`None` for an unknown index).
    pub fn bsdf(&self, material: usize) -> Option<&Bsdf> {
        self.bsdfs.get(material)
    }
}
