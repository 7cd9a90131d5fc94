//! The model of `bumpmap` and `normalmap`: a nested BSDF evaluated in a
//! tilted shading frame, as Mitsuba 3's adapters do (docs/math.md §18.5).
//!
//! Both directions are turned into the tilted frame and handed to the
//! nested BSDF; a direction on different sides of the tilted and the
//! surface's shading normals is not scattered (no light leaks through the
//! tilt). Our BSDFs exclude the cosine that Mitsuba's include, and the
//! integrators multiply by the cosine to the *surface's* shading normal,
//! so the value is the nested one times `|cos θ'_i| / |cos θ_i|`: the
//! nested BSDF's cosine-weighted response in its own frame, as Mitsuba's.
//! Densities are of directions, the same in either frame.
//!
//! A tilted frame lights a Lambertian surface as a Lambertian one is not
//! lit around the surface's normal, so the model has no Lambertian part:
//! the irradiance cache does not serve it, its light is sampled per pixel.

use glam::DVec3;

use super::{Bsdf, BsdfFlags, LobeSample, Model};
use crate::color::Rgb;
use crate::sphere::Frame;

/// A BSDF in a tilted frame; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct Perturbed {
    /// The tilted normal in the surface's shading frame, unit, before it is
    /// turned towards the viewer.
    pub normal: DVec3,
    /// The direction the tilted frame's tangent follows (∂p/∂u, or the
    /// shading frame's tangent), local frame.
    pub tangent: DVec3,
    /// Mitsuba's `flip_invalid_normals`: where the viewer sees the tilted
    /// normal from behind, its tangential part is mirrored.
    pub flip_invalid_normals: bool,
    /// Mitsuba's `use_shadowing_function`: Conty Estevez et al.'s (2019)
    /// microfacet shadowing against the bump terminator.
    pub shadowing: bool,
    pub bsdf: Box<Bsdf>,
}

impl Perturbed {
    /// The tilted frame seen from `wo`, local frame: the normal (mirrored
    /// about the surface normal's axis where `wo` sees it from behind) and
    /// the tangent made orthogonal to it (Gram–Schmidt).
    fn frame(&self, wo: DVec3) -> Frame {
        let mut n = self.normal;
        if self.flip_invalid_normals && wo.z * wo.dot(n) <= 0.0 {
            n = DVec3::new(-n.x, -n.y, n.z);
        }
        match (self.tangent - n * n.dot(self.tangent)).try_normalize() {
            Some(s) => Frame {
                s,
                t: n.cross(s),
                n,
            },
            None => Frame::from_normal(n),
        }
    }

    /// What scales a value of the nested BSDF at `wi` (tilted-frame
    /// direction `wi_t`): the cosine ratio and the shadowing term, zero on
    /// different sides of the two normals.
    fn factor(&self, frame: &Frame, wi: DVec3, wi_t: DVec3) -> f64 {
        if wi.z * wi_t.z <= 0.0 {
            return 0.0;
        }
        let shadow = if self.shadowing {
            shadow_terminator(frame.n, wi)
        } else {
            1.0
        };
        wi_t.z.abs() / wi.z.abs() * shadow
    }
}

/// The nested BSDF of a bump or normal map's `template`, whose
/// precomputed tables the nested build reuses.
pub(super) fn nested_template(template: Option<&Bsdf>) -> Option<&Bsdf> {
    match template {
        Some(Bsdf::NormalMap(p) | Bsdf::BumpMap(p)) => Some(&p.bsdf),
        _ => None,
    }
}

/// Conty Estevez et al. 2019, "A microfacet-based shadowing function to solve
/// the bump terminator problem" (Ray Tracing Gems ch. 12): the tilt as a
/// microfacet slope, `α² = min(tan²θ_n / 8, 1)`, shadowing
/// `2 / (1 + √(1 + α² tan²θ_i))`; both angles to the surface's normal.
fn shadow_terminator(n: DVec3, wi: DVec3) -> f64 {
    let tan2 = |v: DVec3| (1.0 - v.z * v.z).max(0.0) / (v.z * v.z);
    let alpha2 = (0.125 * tan2(n)).min(1.0);
    2.0 / (1.0 + (1.0 + alpha2 * tan2(wi)).sqrt())
}

impl Model for Perturbed {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        let frame = self.frame(wo);
        let wi_t = frame.to_local(wi);
        match self.factor(&frame, wi, wi_t) {
            0.0 => Rgb::BLACK,
            k => self.bsdf.eval(frame.to_local(wo), wi_t) * k,
        }
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let frame = self.frame(wo);
        let wi_t = frame.to_local(wi);
        if wi.z * wi_t.z <= 0.0 {
            return 0.0;
        }
        self.bsdf.pdf(frame.to_local(wo), wi_t)
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        let frame = self.frame(wo);
        let s = self.bsdf.sample(frame.to_local(wo), u_lobe, u)?;
        let wi = frame.to_world(s.wi);
        match self.factor(&frame, wi, s.wi) {
            0.0 => None,
            k => Some(LobeSample {
                wi,
                value: s.value * k,
                ..s
            }),
        }
    }

    /// The nested BSDF's, its Lambertian part counted as glossy (module docs).
    fn flags(&self) -> BsdfFlags {
        let nested = self.bsdf.flags();
        BsdfFlags {
            diffuse: false,
            glossy: nested.glossy || nested.diffuse,
            ..nested
        }
    }

    fn is_black(&self) -> bool {
        self.bsdf.is_black()
    }

    fn scatters_towards(&self, wo: DVec3) -> bool {
        self.bsdf.scatters_towards(self.frame(wo).to_local(wo))
    }

    /// The tilted frame turns with the surface's tangent.
    fn is_anisotropic(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;
    use serde_json::json;

    use super::*;
    use crate::optics::chi_square;
    use crate::scene::material::{Material, Params};

    /// The nested BSDF of document `doc` in a frame tilted to `normal`.
    fn tilted(normal: DVec3, doc: serde_json::Value) -> Perturbed {
        let mut params = doc.as_object().unwrap().clone();
        let kind = params.remove("type").unwrap();
        let mut params = Params::new("test", params);
        let material = Material::parse(kind.as_str().unwrap(), &mut params, "test").unwrap();
        Perturbed {
            normal: normal.normalize(),
            tangent: DVec3::X,
            flip_invalid_normals: true,
            shadowing: true,
            bsdf: Box::new(Bsdf::from(&material)),
        }
    }

    #[test]
    fn an_untilted_frame_is_the_nested_bsdf() {
        let p = tilted(DVec3::Z, json!({"type": "roughconductor", "alpha": 0.3}));
        let (wo, wi) = (
            DVec3::new(0.3, -0.2, 0.9).normalize(),
            DVec3::new(-0.5, 0.1, 0.7).normalize(),
        );
        let d = p.eval(wo, wi) - p.bsdf.eval(wo, wi);
        assert!(d.max_component().abs() < 1e-12, "{d:?}");
        assert_eq!(p.pdf(wo, wi), p.bsdf.pdf(wo, wi));
    }

    #[test]
    fn a_tilted_lambertian_surface_follows_the_cosine_to_its_tilted_normal() {
        let n = DVec3::new(0.4, 0.1, 1.0).normalize();
        let mut p = tilted(n, json!({"type": "diffuse", "reflectance": 0.6}));
        p.shadowing = false;
        let wo = DVec3::new(0.1, 0.2, 1.0).normalize();
        for wi in [DVec3::new(0.5, 0.3, 0.6), DVec3::new(-0.2, 0.6, 0.3)] {
            let wi = wi.normalize();
            // f cos θ_i (what the integrators weigh) = ρ/π · cos to the tilted normal.
            let got = p.eval(wo, wi).r * wi.z;
            let want = 0.6 / std::f64::consts::PI * n.dot(wi);
            assert!((got - want).abs() < 1e-12, "{got} {want}");
        }
        // Below the tilted normal though above the surface's: no light.
        let grazing = DVec3::new(-1.0, 0.0, 0.3).normalize();
        assert!(n.dot(grazing) < 0.0);
        assert_eq!(p.eval(wo, grazing).r, 0.0);
        assert_eq!(p.pdf(wo, grazing), 0.0);
    }

    #[test]
    fn samples_follow_the_density_and_carry_evals_value() {
        let mut rng = Pcg64::seed_from_u64(17);
        for shadowing in [false, true] {
            let mut p = tilted(
                DVec3::new(-0.3, 0.2, 1.0),
                json!({"type": "roughplastic", "alpha": 0.3, "diffuse_reflectance": 0.4}),
            );
            p.shadowing = shadowing;
            for wo in [
                DVec3::new(0.4, 0.2, 0.8).normalize(),
                DVec3::new(-0.9, 0.1, 0.2).normalize(),
            ] {
                let test = chi_square::of_directions(
                    || {
                        p.sample(wo, rng.random(), [rng.random(), rng.random()])
                            .map(|s| s.wi)
                    },
                    |wi| p.pdf(wo, wi),
                    100_000,
                    (16, 24),
                );
                assert!(test.passes(), "from {wo}: {test}");
                for _ in 0..200 {
                    let Some(s) = p.sample(wo, rng.random(), [rng.random(), rng.random()]) else {
                        continue;
                    };
                    let (f, pdf) = (p.eval(wo, s.wi), p.pdf(wo, s.wi));
                    assert!((pdf - s.pdf).abs() <= 1e-9 * pdf, "{pdf} {s:?}");
                    assert!((f - s.value).max_component().abs() <= 1e-9 * f.max_component());
                }
            }
        }
    }

    #[test]
    fn a_white_tilted_surface_keeps_at_most_the_light_it_gets() {
        // White furnace: `∫ f cos θ_i dω_i` ≤ 1, and near 1 for a small tilt
        // without shadowing (only light between the two horizons is lost).
        let mut rng = Pcg64::seed_from_u64(23);
        for (tilt, shadowing, low) in [(0.1, false, 0.97), (0.5, true, 0.6)] {
            let mut p = tilted(
                DVec3::new(tilt, -0.5 * tilt, 1.0),
                json!({"type": "diffuse", "reflectance": 1.0}),
            );
            p.shadowing = shadowing;
            for wo in [DVec3::Z, DVec3::new(0.6, 0.1, 0.5).normalize()] {
                let n = 100_000;
                let mut sum = 0.0;
                for _ in 0..n {
                    let u = [rng.random(), rng.random()];
                    if let Some(s) = p.sample(wo, rng.random(), u) {
                        sum += s.value.r * s.wi.z.abs() / s.pdf;
                    }
                }
                let albedo = sum / n as f64;
                assert!(
                    albedo <= 1.0 + 1e-9 && albedo > low,
                    "albedo {albedo} from {wo}"
                );
            }
        }
    }

    #[test]
    fn without_shadowing_a_tilted_reciprocal_bsdf_stays_reciprocal() {
        // `f(a, b) |cos θ_b| / |cos θ'_b|` is the nested BSDF in the tilted
        // frame, symmetric when the nested one is (where neither
        // direction's view flips the normal).
        let mut p = tilted(
            DVec3::new(0.2, -0.3, 1.0),
            json!({"type": "roughconductor", "alpha": 0.4}),
        );
        p.shadowing = false;
        let n = p.normal;
        let (a, b) = (
            DVec3::new(0.3, 0.1, 0.9).normalize(),
            DVec3::new(-0.2, 0.4, 0.8).normalize(),
        );
        let ab = p.eval(a, b) * (b.z / n.dot(b));
        let ba = p.eval(b, a) * (a.z / n.dot(a));
        assert!(ab.max_component() > 0.0);
        assert!((ab - ba).max_component().abs() < 1e-12, "{ab:?} {ba:?}");
    }
}
