//! Direct light at a surface point by stratified light samples (next-event
//! estimation through the whole BSDF, docs/math.md §1): the `L_direct` term
//! of the cache integrator's shading (`shade`).

use glam::DVec3;
use rand::{Rng, RngExt};

use crate::render::strata::{GridStrata, SharedStrata};
use crate::render::{Bsdf, PixelSample, Rgb, TraceStats, Transport, power_heuristic};
use crate::scene::SurfaceHit;
use crate::sphere::Frame;

/// A surface point about to reflect light towards `wo`: its hit, shading
/// frame, BSDF and the outgoing direction in that frame.
pub(super) struct Surface<'h> {
    pub hit: &'h SurfaceHit,
    pub frame: Frame,
    pub bsdf: &'h Bsdf,
    pub wo_local: DVec3,
}

/// `∫ f_r L_direct cos θ dω` by `n` light samples whose area/direction
/// numbers are stratified: on the shared pattern of `sample` (see
/// `CachedIntegrator::outgoing_radiance`), else on a near-square grid of `n`
/// cells. Either way every sample is uniform on its own, so the mean is
/// unbiased; stratification keeps penumbrae smooth.
///
/// With `mis`, each sample of a light that a BSDF sample could also find
/// (not a delta light) carries the power-heuristic weight of `n` light
/// samples against one BSDF sample ([`mis_weights`]): the caller must then
/// add that BSDF sample's direct emission with the complementary weight,
/// and together they are unbiased (Veach 1997, §9.2.4, docs/math.md §18.3).
pub(super) fn direct_radiance<R: Rng + ?Sized>(
    transport: &Transport,
    s: &Surface,
    n: u32,
    sample: Option<PixelSample>,
    mis: bool,
    rng: &mut R,
    stats: &mut TraceStats,
) -> Rgb {
    let scene = transport.scene();
    let hit = s.hit;
    let shared = sample.map(|p| {
        let count = u64::from(p.count) * u64::from(n);
        (
            SharedStrata::new(count, p.pattern),
            u64::from(p.index) * u64::from(n),
        )
    });
    let own = GridStrata::new(n);
    let mut sum = Rgb::BLACK;
    for k in 0..n {
        let jitter = [rng.random(), rng.random()];
        let u = match &shared {
            Some((strata, first)) => strata.sample(first + u64::from(k), jitter),
            None => own.sample(k, jitter),
        };
        let Some(light) = transport
            .lights()
            .sample(scene, hit.position, rng.random(), u)
        else {
            continue;
        };
        let wi = s.frame.to_local(light.wi);
        let f = s.bsdf.eval(s.wo_local, wi);
        if f.is_black() || light.radiance.is_black() {
            continue;
        }
        if light.visible_from(scene, hit.position, hit.normal, stats) {
            let weight = if mis && !light.delta {
                mis_weights(n, light.pdf, s.bsdf.pdf(s.wo_local, wi)).0
            } else {
                1.0
            };
            sum += f * light.radiance * (weight * wi.z.abs() / light.pdf);
        }
    }
    sum * (1.0 / f64::from(n))
}

/// Power-heuristic weights `(light, bsdf)` of a direction that `n` light
/// samples choose with solid-angle density `light_pdf` each and one BSDF
/// sample with `bsdf_pdf` (the multi-sample power heuristic, Veach 1997
/// §9.2.4: counts multiply densities); they sum to one.
pub(super) fn mis_weights(n: u32, light_pdf: f64, bsdf_pdf: f64) -> (f64, f64) {
    let lights = f64::from(n) * light_pdf;
    (
        power_heuristic(lights, bsdf_pdf),
        power_heuristic(bsdf_pdf, lights),
    )
}
