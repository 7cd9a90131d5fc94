//! Light sources: area lights attached to shapes (`area.rs`), and the
//! delta lights a scene lists under `lights` (Mitsuba 3's `point`, `spot`
//! and `directional`). Environment lighting is separate
//! ([`Environment`](super::Environment)).
//!
//! A light document is `{"type": PLUGIN, PARAMETER: value, …}` with
//! Mitsuba's plugin and parameter names. Each light has its own file below
//! holding its parameters' docs, their parsing and validation through
//! `Params`, and its behaviour for next-event estimation ([`Light`]: the
//! reach that weighs its selection at a point, and sampling a direction
//! towards it); the `plugins!` invocation below is the registry of the
//! `lights` plugins: each line declares the light's module and generates
//! its [`Emitter`] variant, its parser entry and its dispatch arm.

use glam::DVec3;
mod area;

use serde_json::{Map, Value};

use super::Scene;
use super::bitmap::Bitmaps;
use super::error::SceneError;
use super::format::EmitterDoc;
use super::params::Params;
use crate::color::Rgb;
pub use area::AreaLight;
use spot::Cone;

/// Largest accepted radiance component, W/(m²·sr); keeps sums finite.
pub const MAX_RADIANCE: f64 = 1e12;

/// What a light does for next-event estimation (pbrt-v4's `Light`
/// interface, §12.1: the importance of its light BVH, `SampleLi`).
pub trait Light {
    /// What choosing the light at a point needs to know of it.
    fn reach(&self, scene: &Scene) -> Reach;

    /// A direction from the shading point `x` towards the light, chosen
    /// with probability `p_select` (folded into the sample's `pdf`), `u`
    /// the point on it; `None` when the sample carries nothing.
    fn sample(&self, scene: &Scene, x: DVec3, p_select: f64, u: [f64; 2]) -> Option<LightSample>;
}

/// The `lights` plugins: `Variant(file::Type) = "name"`, one line each.
/// For each line the macro declares `pub mod file;` (the light's file),
/// the variant `Emitter::Variant(Type)`, the parser of `"name"` (the
/// type's `parse(&mut Params)`) and the arm dispatching to its [`Light`]
/// implementation. Area lights, nested in shapes, are the one variant
/// outside it.
macro_rules! plugins {
    ($($variant:ident($file:ident::$plugin:ident) = $name:literal,)*) => {
        $(pub mod $file;)*

        /// A light source with its parameters validated (each light's
        /// file documents its fields).
        #[derive(Clone, Debug, PartialEq)]
        pub enum Emitter {
            Area(AreaLight),
            $($variant($file::$plugin),)*
        }

        /// Every light plugin of a scene's `lights`, by its `type`.
        const LIGHTS: &[(&str, Parse)] = &[
            $(($name, |params| Ok(Emitter::$variant($file::$plugin::parse(params)?))),)*
        ];

        impl Emitter {
            /// The light's behaviour, for dispatch.
            fn light(&self) -> &dyn Light {
                match self {
                    Emitter::Area(a) => a,
                    $(Emitter::$variant(l) => l,)*
                }
            }
        }
    };
}

plugins! {
    Point(point::PointLight) = "point",
    Spot(spot::SpotLight) = "spot",
    Directional(directional::DirectionalLight) = "directional",
}

impl Emitter {
    /// The emitting shape of an area light.
    pub fn shape(&self) -> Option<usize> {
        match self {
            Emitter::Area(area) => Some(area.shape),
            _ => None,
        }
    }

    /// Whether the light is a Dirac delta in position or direction: no ray
    /// can hit it, only light samples reach it.
    pub fn is_delta(&self) -> bool {
        !matches!(self, Emitter::Area(_))
    }

    /// What choosing the light at a point needs to know of it.
    pub fn reach(&self, scene: &Scene) -> Reach {
        self.light().reach(scene)
    }

    /// A direction from `x` towards the light, chosen with probability
    /// `p_select`; see [`Light::sample`].
    pub fn sample(
        &self,
        scene: &Scene,
        x: DVec3,
        p_select: f64,
        u: [f64; 2],
    ) -> Option<LightSample> {
        self.light().sample(scene, x, p_select, u)
    }
}

/// A direction towards a light with what it carries.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit world direction from the shading point towards the light.
    pub wi: DVec3,
    /// Emitted radiance arriving along `-wi` if nothing is in between, W/(m²·sr).
    pub radiance: Rgb,
    /// Solid-angle density including light selection, sr⁻¹.
    pub pdf: f64,
    /// The light's point (with its surface normal on an area light), for
    /// the shadow ray; `None` for light from infinitely far (the environment,
    /// a directional light), whose shadow ray is unbounded.
    pub target: Option<(DVec3, Option<DVec3>)>,
    /// Whether the light is a Dirac delta (point, spot, directional): no
    /// BSDF-sampled ray can find it, so it needs no MIS weight.
    pub delta: bool,
}

/// The sample of a light at the point `position` whose intensity towards
/// `x` is `intensity` (W/sr), chosen with probability `p_select`: its one
/// direction, carrying `I/d²` (the delta's weight, so `radiance / pdf` is
/// its contribution over the choice).
fn toward_point(
    x: DVec3,
    position: &[f64; 3],
    intensity: Rgb,
    p_select: f64,
) -> Option<LightSample> {
    let p = DVec3::from_array(*position);
    let d = p - x;
    let dist2 = d.length_squared();
    (dist2 > 0.0).then(|| LightSample {
        wi: d / dist2.sqrt(),
        radiance: intensity * (1.0 / dist2),
        pdf: p_select,
        target: Some((p, None)),
        delta: true,
    })
}

/// What choosing a light at a point needs to know of it: its estimated
/// irradiance there is [`Reach::at`] (docs/math.md §15.2).
#[derive(Clone, Copy, Debug)]
pub enum Reach {
    /// An emitting surface: `A lum(L̄)`, its bounding sphere's centre and
    /// squared radius.
    Surface {
        strength: f64,
        center: DVec3,
        radius2: f64,
    },
    /// A point light, or a spot light with its cone: `lum(I)`.
    Point {
        position: DVec3,
        intensity: f64,
        cone: Option<Cone>,
    },
    /// Light from infinitely far, the same at every point: `lum(E)` of a
    /// directional light, `π lum(L̄)` of the environment.
    Distant(f64),
}

impl Reach {
    /// Estimated irradiance (luminance) the light can bring to `x`, W/m²;
    /// 0 where it brings nothing.
    pub fn at(&self, x: DVec3) -> f64 {
        match *self {
            Reach::Surface {
                strength,
                center,
                radius2,
            } => strength / (center - x).length_squared().max(radius2),
            Reach::Point {
                position,
                intensity,
                cone,
            } => {
                let d = x - position;
                let dist2 = d.length_squared();
                if dist2 <= 0.0 {
                    return 0.0;
                }
                let falloff = cone.map_or(1.0, |c| c.falloff(d / dist2.sqrt()));
                intensity * falloff / dist2
            }
            Reach::Distant(e) => e,
        }
    }
}

/// Validates an RGB radiance: finite, non-negative, ≤ [`MAX_RADIANCE`].
pub(crate) fn check_radiance(value: [f64; 3], field: &str) -> Result<[f64; 3], SceneError> {
    for (i, x) in value.iter().enumerate() {
        if !(0.0..=MAX_RADIANCE).contains(x) {
            return Err(SceneError::invalid(
                format!("{field}[{i}]"),
                format!("{x} is not a radiance in [0, {MAX_RADIANCE:e}]"),
            ));
        }
    }
    Ok(value)
}

/// A light plugin's parser: its parameters to an emitter.
type Parse = fn(&mut Params) -> Result<Emitter, SceneError>;

/// The light plugin names a scene's `lights` accept, for messages and docs.
pub fn light_names() -> Vec<&'static str> {
    LIGHTS.iter().map(|(name, _)| *name).collect()
}

/// An emitted quantity (`intensity`, `irradiance`): a colour in
/// `[0, MAX_RADIANCE]`, `default` when absent.
pub(crate) fn power(params: &mut Params, name: &str, default: f64) -> Result<[f64; 3], SceneError> {
    let value = params.color(name)?.unwrap_or([default; 3]);
    check_radiance(value, &params.field(name))
}

impl Emitter {
    /// The area light `doc` of shape `shape`; `field` names it in errors,
    /// a texture's images are read through `bitmaps`.
    pub(crate) fn from_doc(
        doc: &EmitterDoc,
        shape: usize,
        field: &str,
        bitmaps: &Bitmaps,
    ) -> Result<Self, SceneError> {
        Ok(Emitter::Area(AreaLight::parse(doc, shape, field, bitmaps)?))
    }

    /// The parameters of a `kind` light document that its plugin does not
    /// take, when the others parse (none otherwise: the loader then
    /// reports the error), so that a translator can drop them.
    pub(crate) fn unknown_parameters(kind: &str, params: &Map<String, Value>) -> Vec<String> {
        let Some((_, parse)) = LIGHTS.iter().find(|(name, _)| *name == kind) else {
            return Vec::new();
        };
        let mut params = Params::new("", params.clone());
        match parse(&mut params) {
            Ok(_) => params.remaining(),
            Err(_) => Vec::new(),
        }
    }

    /// Whether parameter `name` of a `kind` light is a colour: an
    /// `[r, g, b]` given alone parses without an error about it.
    pub(crate) fn takes_colour(kind: &str, name: &str) -> bool {
        let Some((_, parse)) = LIGHTS.iter().find(|(n, _)| *n == kind) else {
            return false;
        };
        let mut doc = Map::new();
        doc.insert(name.to_string(), Value::from(vec![0.5, 0.25, 0.125]));
        match parse(&mut Params::new("", doc)) {
            Ok(_) => true,
            Err(e) => e.field().and_then(|f| f.strip_prefix('.')) != Some(name),
        }
    }

    /// Validates one `lights[i]` entry (`field` its path): `type` names a
    /// plugin of [`LIGHTS`], the rest are its parameters.
    pub(crate) fn from_light_doc(
        doc: &Map<String, Value>,
        field: &str,
    ) -> Result<Self, SceneError> {
        let mut map = doc.clone();
        let kind = match map.remove("type") {
            Some(Value::String(kind)) => kind,
            _ => return Err(SceneError::invalid(field, "missing field `type`")),
        };
        let Some((_, parse)) = LIGHTS.iter().find(|(name, _)| *name == kind) else {
            let known: Vec<&str> = LIGHTS.iter().map(|(name, _)| *name).collect();
            return Err(SceneError::invalid(
                format!("{field}.type"),
                format!("unknown light type {kind:?} (known: {})", known.join(", ")),
            ));
        };
        let mut params = Params::new(field, map);
        let emitter = parse(&mut params)?;
        params.finish()?;
        Ok(emitter)
    }
}
