//! Colour: linear RGB triples for radiance, irradiance, reflectance and
//! path throughput, and their luminance. The lowest layer: the scene
//! description, light transport and the estimators all read it.
//!
//! A dedicated type rather than `glam::DVec3` so that colours and geometric
//! vectors cannot be mixed up by accident: a direction never gets multiplied
//! into a throughput. Channels are linear (no gamma) and in the scene's units,
//! e.g. W/(m²·sr) for radiance and W/m² for irradiance.

pub mod cie;
pub mod spectrum;

use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Sub};

/// Linear RGB as three numbers in channel order: the form scene documents
/// are parsed into and textures store ([`Rgb`] once shading starts).
pub type RgbArray = [f64; 3];

/// The weights of luminance `Y = w·(r, g, b)`: the CIE Y of the linear sRGB
/// (Rec. 709) primaries with a D65 white, as Mitsuba 3 computes it
/// (`luminance()` in its `core/spectrum.h`). They sum to 1, so white has
/// unit luminance.
pub const LUMINANCE_WEIGHTS: RgbArray = [0.212671, 0.715160, 0.072169];

/// Luminance of linear RGB `c` ([`LUMINANCE_WEIGHTS`]); used to weigh light
/// sources, lobes and textures' means, never for output.
pub fn luminance(c: RgbArray) -> f64 {
    (0..3).map(|i| LUMINANCE_WEIGHTS[i] * c[i]).sum()
}

/// Linear RGB value; arithmetic is per channel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rgb {
    pub r: f64,
    pub g: f64,
    pub b: f64,
}

impl Rgb {
    pub const BLACK: Rgb = Rgb::splat(0.0);
    pub const WHITE: Rgb = Rgb::splat(1.0);

    pub const fn new(r: f64, g: f64, b: f64) -> Self {
        Self { r, g, b }
    }

    pub const fn splat(v: f64) -> Self {
        Self::new(v, v, v)
    }

    pub const fn from_array(c: [f64; 3]) -> Self {
        Self::new(c[0], c[1], c[2])
    }

    pub const fn to_array(self) -> [f64; 3] {
        [self.r, self.g, self.b]
    }

    /// Luminance ([`luminance`]).
    pub fn luminance(self) -> f64 {
        luminance(self.to_array())
    }

    pub fn max_component(self) -> f64 {
        self.r.max(self.g).max(self.b)
    }

    pub fn min_component(self) -> f64 {
        self.r.min(self.g).min(self.b)
    }

    pub fn is_finite(self) -> bool {
        self.r.is_finite() && self.g.is_finite() && self.b.is_finite()
    }

    pub fn is_black(self) -> bool {
        self.r == 0.0 && self.g == 0.0 && self.b == 0.0
    }

    pub fn map(self, f: impl Fn(f64) -> f64) -> Self {
        Self::new(f(self.r), f(self.g), f(self.b))
    }
}

impl Add for Rgb {
    type Output = Rgb;
    fn add(self, o: Rgb) -> Rgb {
        Rgb::new(self.r + o.r, self.g + o.g, self.b + o.b)
    }
}

impl AddAssign for Rgb {
    fn add_assign(&mut self, o: Rgb) {
        *self = *self + o;
    }
}

impl Sub for Rgb {
    type Output = Rgb;
    fn sub(self, o: Rgb) -> Rgb {
        Rgb::new(self.r - o.r, self.g - o.g, self.b - o.b)
    }
}

impl Mul for Rgb {
    type Output = Rgb;
    fn mul(self, o: Rgb) -> Rgb {
        Rgb::new(self.r * o.r, self.g * o.g, self.b * o.b)
    }
}

impl MulAssign for Rgb {
    fn mul_assign(&mut self, o: Rgb) {
        *self = *self * o;
    }
}

impl Mul<f64> for Rgb {
    type Output = Rgb;
    fn mul(self, s: f64) -> Rgb {
        self.map(|c| c * s)
    }
}

impl Mul<Rgb> for f64 {
    type Output = Rgb;
    fn mul(self, c: Rgb) -> Rgb {
        c * self
    }
}

impl MulAssign<f64> for Rgb {
    fn mul_assign(&mut self, s: f64) {
        *self = *self * s;
    }
}

impl Div<f64> for Rgb {
    type Output = Rgb;
    fn div(self, s: f64) -> Rgb {
        self.map(|c| c / s)
    }
}

impl std::iter::Sum for Rgb {
    fn sum<I: Iterator<Item = Rgb>>(iter: I) -> Rgb {
        iter.fold(Rgb::BLACK, |a, b| a + b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arithmetic_is_per_channel() {
        let a = Rgb::new(1.0, 2.0, 3.0);
        let b = Rgb::new(0.5, 0.25, 2.0);
        assert_eq!(a * b, Rgb::new(0.5, 0.5, 6.0));
        assert_eq!(a + b - b, a);
        assert_eq!(2.0 * a / 2.0, a);
        assert_eq!([a, b].into_iter().sum::<Rgb>(), Rgb::new(1.5, 2.25, 5.0));
        assert_eq!(a.max_component(), 3.0);
    }

    #[test]
    fn white_has_unit_luminance() {
        assert!((Rgb::WHITE.luminance() - 1.0).abs() < 1e-12);
        assert!(Rgb::BLACK.is_black());
    }
}
