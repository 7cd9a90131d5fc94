//! Spectra read into linear sRGB as Mitsuba 3's RGB variants read them
//! (docs/math.md §18.4), so a scene written with `<spectrum>` values looks
//! here as it does in Mitsuba's `scalar_rgb`.
//!
//! A spectrum is either one value for every wavelength or samples
//! `(λᵢ, vᵢ)` with increasing wavelengths in nm, linear between them and
//! zero outside them. What its RGB is depends on what it describes
//! ([`SpectrumUse`]): a reflectance is seen under D65 (sRGB's white), so a
//! flat reflectance is grey; an emitter's spectrum is light itself, so a
//! flat one is the equal-energy white, which in sRGB is slightly purple.

use super::cie;
use super::{Rgb, RgbArray};

/// What a spectrum describes: the flags Mitsuba 3's `Properties` reads a
/// texture property with (`get_texture`, `get_unbounded_texture`,
/// `get_emissive_texture`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectrumUse {
    /// A reflectance or transmittance: seen under D65, clipped to [0, 1].
    Reflectance,
    /// A reflectance-like quantity without an upper bound (a conductor's
    /// `eta` and `k`): seen under D65, negatives clipped to 0.
    Unbounded,
    /// Emitted radiance, intensity or irradiance: not weighted by D65,
    /// negatives clipped to 0.
    Emission,
}

/// Mitsuba's `MI_CIE_Y_NORMALIZATION`: one over ∫ ȳ(λ) dλ as its RGB
/// variants sum it (1,000 points over 360–830 nm), so that a unit spectrum
/// has unit luminance.
const Y_NORMALISATION: f64 = 1.0 / 106.750_259_399_414_06;
/// Mitsuba's `MI_CIE_D65_NORMALIZATION`: D65 scaled to unit luminance.
const D65_NORMALISATION: f64 = 1.0 / 98.997_417_518_762_55;
/// Points of the sum that integrates a sampled spectrum against the
/// colour-matching functions, evenly spread over 360–830 nm, ends included.
const STEPS: usize = 1000;

/// CIE XYZ to linear sRGB (Rec. 709 primaries, D65 white), the matrix of
/// Mitsuba 3's `xyz_to_srgb`.
const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.240479, -1.537150, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];

fn xyz_to_srgb(xyz: [f64; 3]) -> RgbArray {
    XYZ_TO_SRGB.map(|row| row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2])
}

/// Table `t` at wavelength `w` (nm), linear between its 5-nm samples and
/// zero outside 360–830 nm.
fn lookup(t: &[f64; cie::SAMPLES], w: f64) -> f64 {
    if !(cie::MIN..=cie::MAX).contains(&w) {
        return 0.0;
    }
    let x = (w - cie::MIN) * (cie::SAMPLES - 1) as f64 / (cie::MAX - cie::MIN);
    let i = (x as usize).min(cie::SAMPLES - 2);
    let f = x - i as f64;
    (1.0 - f) * t[i] + f * t[i + 1]
}

/// The RGB of a spectrum that is `value` at every wavelength. A reflectance
/// is grey; emitted light is `value` times the equal-energy white
/// `xyz_to_srgb(1, 1, 1)` ≈ (1.2048, 0.9483, 0.9089).
pub fn uniform_to_rgb(value: f64, usage: SpectrumUse) -> RgbArray {
    match usage {
        SpectrumUse::Emission => xyz_to_srgb([1.0; 3]).map(|c| value * c),
        SpectrumUse::Reflectance | SpectrumUse::Unbounded => [value; 3],
    }
}

/// A spectrum sampled at increasing wavelengths (nm), linear between its
/// samples and zero outside them.
#[derive(Clone, Debug, PartialEq)]
pub struct SampledSpectrum {
    wavelengths: Vec<f64>,
    values: Vec<f64>,
}

impl SampledSpectrum {
    /// At least two finite samples at strictly increasing wavelengths.
    pub fn new(samples: Vec<(f64, f64)>) -> Result<Self, String> {
        if samples.len() < 2 {
            return Err(format!(
                "a sampled spectrum needs at least 2 samples, found {}",
                samples.len()
            ));
        }
        if let Some((w, v)) = samples
            .iter()
            .find(|(w, v)| !w.is_finite() || !v.is_finite())
        {
            return Err(format!("sample {w}:{v} is not finite"));
        }
        if let Some(pair) = samples.windows(2).find(|p| p[1].0 <= p[0].0) {
            return Err(format!(
                "wavelengths must increase, found {} after {}",
                pair[1].0, pair[0].0
            ));
        }
        let (wavelengths, values) = samples.into_iter().unzip();
        Ok(Self {
            wavelengths,
            values,
        })
    }

    /// Mitsuba's inline form: `"λ1:v1, λ2:v2, …"` (commas or spaces apart).
    pub fn parse_pairs(text: &str) -> Result<Self, String> {
        let pairs = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|pair| {
                pair.split_once(':')
                    .and_then(|(w, v)| Some((w.parse().ok()?, v.parse().ok()?)))
                    .ok_or_else(|| format!("{pair:?} is not `wavelength:value`"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Self::new(pairs)
    }

    /// A spectrum file as Mitsuba reads one (`.spd`): a wavelength and a
    /// value per line, separated by white space; lines starting with `#`
    /// and empty lines skipped. Errors name the line.
    pub fn parse_file(text: &str) -> Result<Self, String> {
        let mut samples = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let mut fields = line.split_whitespace().map(str::parse::<f64>);
            match (fields.next(), fields.next()) {
                (Some(Ok(w)), Some(Ok(v))) => samples.push((w, v)),
                _ => {
                    return Err(format!(
                        "line {}: {line:?} is not a wavelength and a value",
                        i + 1
                    ));
                }
            }
        }
        Self::new(samples)
    }

    /// The spectrum's value at wavelength `w` (nm).
    fn at(&self, w: f64) -> f64 {
        let (first, last) = (
            self.wavelengths[0],
            self.wavelengths[self.wavelengths.len() - 1],
        );
        if w < first || w > last {
            return 0.0;
        }
        let i = self
            .wavelengths
            .partition_point(|&x| x <= w)
            .clamp(1, self.wavelengths.len() - 1)
            - 1;
        let (w0, w1) = (self.wavelengths[i], self.wavelengths[i + 1]);
        let f = (w - w0) / (w1 - w0);
        (1.0 - f) * self.values[i] + f * self.values[i + 1]
    }

    /// Linear sRGB of the spectrum read as `usage` describes: XYZ =
    /// ∫ s(λ) [D65(λ)] (x̄, ȳ, z̄)(λ) dλ over 360–830 nm, summed at
    /// [`STEPS`] points as Mitsuba's `spectrum_list_to_srgb` does, then
    /// Rec. 709; clipped to [0, 1] for a reflectance, at 0 otherwise.
    pub fn to_rgb(&self, usage: SpectrumUse) -> Rgb {
        let under_d65 = usage != SpectrumUse::Emission;
        let mut xyz = [0.0; 3];
        for k in 0..STEPS {
            let w = cie::MIN + k as f64 / (STEPS - 1) as f64 * (cie::MAX - cie::MIN);
            let mut s = self.at(w);
            if under_d65 {
                s *= lookup(&cie::D65, w) * D65_NORMALISATION;
            }
            for (c, table) in [&cie::X_BAR, &cie::Y_BAR, &cie::Z_BAR]
                .into_iter()
                .enumerate()
            {
                xyz[c] += s * lookup(table, w);
            }
        }
        let scale = (cie::MAX - cie::MIN) * Y_NORMALISATION / STEPS as f64;
        let rgb = xyz_to_srgb(xyz.map(|c| c * scale));
        Rgb::from_array(rgb.map(|c| match usage {
            SpectrumUse::Reflectance => c.clamp(0.0, 1.0),
            SpectrumUse::Unbounded | SpectrumUse::Emission => c.max(0.0),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mitsuba 3.9.1's `spectrum_list_to_srgb` of the same spectra (printed
    /// by `docs/validation/mitsuba_spectra.py`).
    #[test]
    fn sampled_spectra_match_mitsubas_rgb() {
        use SpectrumUse::*;
        let cases = [
            ("360:1, 830:1", Reflectance, [0.998983, 0.998872, 0.998802]),
            ("360:1, 830:1", Emission, [1.20488, 0.948229, 0.909267]),
            (
                "400:0.1, 500:0.8, 600:0.3, 700:0.9",
                Reflectance,
                [0.284288, 0.61385, 0.46843],
            ),
            (
                "400:0.1, 500:0.8, 600:0.3, 700:0.9",
                Unbounded,
                [0.284288, 0.61385, 0.46843],
            ),
            (
                "400:0.1, 500:0.8, 600:0.3, 700:0.9",
                Emission,
                [0.386137, 0.578101, 0.415127],
            ),
            (
                "450:2, 550:0.5, 650:3",
                Reflectance,
                [1.0, 0.918223, 0.942416],
            ),
            (
                "450:2, 550:0.5, 650:3",
                Unbounded,
                [1.95572, 0.918223, 0.942416],
            ),
            (
                "450:2, 550:0.5, 650:3",
                Emission,
                [2.30135, 0.871312, 0.785348],
            ),
            ("520:0, 525:5, 530:0", Reflectance, [0.0, 0.345927, 0.0]),
            ("520:0, 525:5, 530:0", Emission, [0.0, 0.322295, 0.0]),
        ];
        for (text, usage, expected) in cases {
            let rgb = SampledSpectrum::parse_pairs(text).unwrap().to_rgb(usage);
            for (got, want) in rgb.to_array().into_iter().zip(expected) {
                // Mitsuba prints 6 digits of f32 tables and sums.
                assert!((got - want).abs() < 2e-5, "{text} as {usage:?}: {rgb:?}");
            }
        }
    }

    #[test]
    fn a_one_valued_spectrum_on_an_emitter_is_the_equal_energy_white() {
        let white = uniform_to_rgb(2.0, SpectrumUse::Emission);
        let mitsuba = [1.20479, 0.948291, 0.908916];
        for c in 0..3 {
            assert!((white[c] - 2.0 * mitsuba[c]).abs() < 1e-5, "{white:?}");
        }
        // Its luminance is the value's: Y of xyz (1, 1, 1) is 1.
        assert!((crate::color::luminance(white) - 2.0).abs() < 1e-4);
        assert_eq!(uniform_to_rgb(0.4, SpectrumUse::Reflectance), [0.4; 3]);
    }

    #[test]
    fn spectrum_files_and_bad_spectra_are_read_or_named() {
        let file = "# a comment\n\n400 0.5\n 500\t0.25 \n600 1\n";
        let s = SampledSpectrum::parse_file(file).unwrap();
        assert_eq!(s.wavelengths, [400.0, 500.0, 600.0]);
        assert_eq!(s.at(450.0), 0.375);
        assert_eq!(s.at(399.0), 0.0);
        let bad = SampledSpectrum::parse_file("400 0.5\n500 x\n").unwrap_err();
        assert!(bad.contains("line 2"), "{bad}");
        for (text, says) in [
            ("500:1", "at least 2"),
            ("500:1, 400:2", "must increase"),
            ("500:1, 600", "wavelength:value"),
            ("500:1, 600:inf", "not finite"),
        ] {
            let e = SampledSpectrum::parse_pairs(text).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }
}
