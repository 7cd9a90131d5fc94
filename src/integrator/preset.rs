//! Named quality presets of camera tiles: every knob of a render (camera
//! rays, passes, path depth and the irradiance cache's options) set once
//! here, so "how good" is asked for by name and explicit knobs only
//! override. Their measured error and time on the bundled scenes are in
//! docs/BENCHMARKS.md ("Presets").
//!
//! A preset renders `passes` passes of `samples_per_pixel` camera rays each
//! (see [`crate::render::TileRequest::pass`]): pass `k` is an independent
//! render with its own camera samples that shares the tile's records, and
//! the mean of passes `0..=k` (`integrator::progressive`, docs/math.md §16.5) is the
//! progressive image after `k + 1` passes; the mean of all is the final one.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::cached::CachedSpec;
use super::spec::{IntegratorSpec, PathSpec};
use crate::render::PathDepth;
use crate::scene::Scene;

/// A named quality level.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The fastest useful look: structure and lighting, visibly noisy (on
    /// the Cornell box cold on two cores: 9.7 % error in 0.25 s, where its
    /// former 8-segment paths and single light samples gave 20 % in 0.2 s;
    /// docs/BENCHMARKS.md "Interactive budgets"). Its records hold paths as
    /// deep as the other presets', so point queries of any usual depth can
    /// read them (the records prior, docs/math.md §10.7).
    Draft,
    /// The default: an interactive first look that a person can judge, a
    /// whole 256² image cold in about a second on two cores (on the Cornell
    /// box 5.2 % error after the first pass at 0.6 s, 3.6 % after the second
    /// at 0.8 s, 3.3 % after the third at 1.0 s; docs/BENCHMARKS.md
    /// "Interactive budgets").
    #[default]
    Preview,
    /// Clean enough to work with in about 2 s: the preview's records placed
    /// at the standard preset's accuracy, in five passes of 4 camera rays,
    /// the later ones where the first left the widest error bars (on the
    /// Cornell box cold on two cores: 5.2 % after the first pass at 1.1 s,
    /// 3.0 % after the third at 1.5 s, 2.7 % after the fifth at 1.9 s,
    /// below path tracing and a denoiser given albedo and normal buffers at
    /// 2 s; docs/BENCHMARKS.md "Interactive budgets").
    Interactive,
    /// A clean image in a few seconds: the final preset's records at half
    /// the directions, in four passes of 16 camera rays (on the Cornell box
    /// cold on two cores: 2.75 % error after the first pass at 1.8 s, 2.3 %
    /// after the third at 3.1 s, below path tracing with a denoiser given
    /// albedo and normal buffers at each; docs/BENCHMARKS.md "Interactive
    /// budgets").
    Standard,
    /// Publication quality: 1024-direction records, four passes of 16
    /// camera rays (on the Cornell box cold on two cores: 1.5 % error in
    /// 5.9 s, where Mitsuba 3 needs about 40–50 times as long;
    /// docs/BENCHMARKS.md "Interactive budgets").
    Final,
}

/// Everything a preset fixes on a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileSettings {
    /// The cache integrator with every knob a preset fixes set
    /// (`reproducible` included: a preset's tiles are the same bytes
    /// whatever ran before).
    pub integrator: IntegratorSpec,
    /// Camera rays per pixel in each pass.
    pub samples_per_pixel: u32,
    /// Passes of the progressive render (≥ 1).
    pub passes: u32,
    /// Longest path in segments from the camera.
    pub max_depth: PathDepth,
    /// Whether tiles are denoised when the request does not say: path
    /// traced tiles are, cached ones not (their records' error is shared
    /// by neighbouring pixels, which a denoiser takes for signal).
    pub denoise: bool,
}

impl TileSettings {
    /// Camera rays per pixel over all passes.
    pub fn total_samples_per_pixel(&self) -> u32 {
        self.samples_per_pixel.saturating_mul(self.passes)
    }
}

impl Preset {
    pub const ALL: [Preset; 5] = [
        Preset::Draft,
        Preset::Preview,
        Preset::Interactive,
        Preset::Standard,
        Preset::Final,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Preset::Draft => "draft",
            Preset::Preview => "preview",
            Preset::Interactive => "interactive",
            Preset::Standard => "standard",
            Preset::Final => "final",
        }
    }

    /// The preset's knobs on `scene`: the irradiance cache's
    /// ([`Preset::settings`]), or path tracing and a denoiser
    /// ([`Preset::path_settings`]) where records do not pay: on a scene
    /// with surfaces that make caustics ([`Scene::has_caustic_surfaces`]), records carry
    /// light that their directions sample badly, and their error shows as
    /// blotches no denoiser removes (docs/math.md §16.7).
    pub fn settings_on(self, scene: &Scene) -> TileSettings {
        if scene.has_caustic_surfaces() {
            self.path_settings()
        } else {
            self.settings()
        }
    }

    /// The preset as path tracing, denoised by default: the cached
    /// preset's passes (so a client's ladder of passes is the same on
    /// every scene), of about its time on the bundled scenes.
    pub fn path_settings(self) -> TileSettings {
        let spp = match self {
            Preset::Draft | Preset::Preview | Preset::Interactive => 4,
            Preset::Standard => 16,
            Preset::Final => 48,
        };
        TileSettings {
            integrator: IntegratorSpec::Path(PathSpec {}),
            samples_per_pixel: spp,
            passes: self.settings().passes,
            max_depth: PathDepth::constant(64),
            denoise: true,
        }
    }

    /// The preset's knobs with the irradiance cache. Records: spherical Fibonacci directions with the
    /// default SE kernel; more directions and paths per direction lower the
    /// records' Monte Carlo noise, a smaller accuracy places more of them
    /// (docs/BENCHMARKS.md "Irradiance cache" for how each knob trades).
    pub fn settings(self) -> TileSettings {
        // (spp per pass, passes, record directions, paths per direction,
        // accuracy, smallest record radius in pixels, light samples, glossy
        // BMC directions)
        let (spp, passes, samples, paths, accuracy, min_pixels, light, glossy) = match self {
            Preset::Draft => (2, 1, 128, 1, 0.5, 12.0, 4, 8),
            Preset::Preview => (4, 3, 384, 2, 0.4, 8.0, 4, 16),
            Preset::Interactive => (4, 5, 384, 2, 0.3, 4.0, 4, 16),
            Preset::Standard => (16, 4, 512, 1, 0.3, 4.0, 4, 32),
            Preset::Final => (16, 4, 1024, 1, 0.25, 3.0, 4, 64),
        };
        // At 1,024 directions a record pays for itself where it serves more
        // than a few pixels: the final preset path traces the tiles where its
        // probe finds more than 0.2 records per pixel (the lego's bricks,
        // 0.23–0.5 per tile: 7.2 % → 4.4 % error over 8×8 blocks in half the
        // time; the Cornell boxes' tiles reach 0.15 and keep their records,
        // as do all the studio's but one edge tile, at 0.25). The standard
        // and interactive presets' 512 and 384 directions keep the same
        // limit; the cheaper presets' records pay at any density seen so far.
        let dense_limit = matches!(self, Preset::Interactive | Preset::Standard | Preset::Final);
        let max_records_per_pixel = dense_limit.then_some(0.2);
        // Every preset's paths may run 64 segments, which leaves no visible
        // truncation and lets the records' rays stop at their first hits and
        // read the scene's secondary cache there (`paths_per_direction` light
        // samples per direction): 2.2× less time × error² on the Cornell box
        // than 4 paths per direction (docs/BENCHMARKS.md "The secondary
        // cache"), for the draft 9.7 % error where its 8-segment paths of
        // 64 directions gave 13.8 % in nearly the same time, and for the
        // preview 3.6 % after its second pass at 0.8 s, where 256 directions
        // of 16-segment paths gave 5.1 % (docs/BENCHMARKS.md "Interactive
        // budgets", stops 62 and 63). A scene or request depth too short for
        // the cache (`AMBIENT_MIN_DEPTH`) gets paths as before: the preview
        // keeps two per direction, as its records serve the records prior of
        // such shallow queries (a variant with one path per direction left a
        // depth-2 calibration test out of its band).
        TileSettings {
            samples_per_pixel: spp,
            passes,
            max_depth: PathDepth::constant(64),
            denoise: false,
            integrator: IntegratorSpec::Cache(CachedSpec {
                samples: Some(samples),
                glossy_samples: Some(glossy),
                paths_per_direction: Some(paths),
                secondary_cache: Some(true),
                accuracy: Some(accuracy),
                light_samples: Some(light),
                min_pixels: Some(min_pixels),
                max_records_per_pixel,
                reproducible: Some(true),
                ..CachedSpec::default()
            }),
        }
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Preset {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Preset::ALL.iter().map(|p| p.name()).collect();
                format!("unknown preset {s:?}; one of {}", names.join(", "))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_resolves_and_quality_grows() {
        let mut last_cost = 0;
        for preset in Preset::ALL {
            let s = preset.settings();
            let integrator = s.integrator.resolve().expect("valid options");
            assert!(integrator.reproducible());
            let config = integrator.cached().expect("the cache integrator");
            assert!(s.passes >= 1 && s.samples_per_pixel >= 1);
            let cost = u64::from(s.total_samples_per_pixel()) * config.paths_per_record();
            assert!(
                cost > last_cost,
                "{preset} is not dearer than the one before"
            );
            last_cost = cost;
            assert_eq!(preset.name().parse::<Preset>(), Ok(preset));
        }
        assert_eq!(Preset::default(), Preset::Preview);
        for preset in Preset::ALL {
            let path = preset.path_settings();
            assert_eq!(path.passes, preset.settings().passes, "{preset}");
            assert!(path.denoise && !preset.settings().denoise);
        }
        assert!("best".parse::<Preset>().unwrap_err().contains("preview"));
    }

    /// The tutorials' box (a glass and a mirror sphere) and the studio (glass,
    /// rough gold, a smooth plastic coat) make caustics; the Cornell box and
    /// the sky scene (Lambertian and Phong lobes, which the cache integrates)
    /// do not.
    #[test]
    fn caustic_surfaces_are_found_by_their_lobes() {
        use crate::scene::material::Material;
        let load = |file: &str| {
            let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
            Scene::load(&root.join(file), root).expect("a bundled scene")
        };
        let caustics = |scene: &Scene| -> Vec<bool> {
            scene
                .materials
                .iter()
                .map(Material::makes_caustics)
                .collect()
        };
        let cbox = load("tests/data/mitsuba-tutorials/cbox.xml");
        assert_eq!(cbox.material_ids[4..], ["glass", "mirror"]);
        assert_eq!(caustics(&cbox), [false, false, false, false, true, true]);
        let studio = load("scenes/studio.xml");
        assert_eq!(studio.material_ids[1..4], ["gold", "glass", "red-plastic"]);
        assert_eq!(caustics(&studio), [false, true, true, true, false]);
        for file in ["scenes/cornell-box.json", "scenes/sky.json"] {
            let scene = load(file);
            assert!(!caustics(&scene).contains(&true), "{file}");
            assert_eq!(Preset::Final.settings_on(&scene), Preset::Final.settings());
        }
        assert_eq!(
            Preset::Final.settings_on(&studio),
            Preset::Final.path_settings()
        );
    }
}
