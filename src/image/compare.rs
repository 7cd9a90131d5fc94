//! Relative RMSE between an image and a reference, the error measure of
//! docs/VALIDATION.md and of the irradiance-cache figures in docs/BENCHMARKS.md
//! (docs/math.md §17).
//!
//! `relative RMSE = sqrt(mean((a − b)²)) / mean(b)`, the means taken over the
//! selected pixels and, for the overall figure, all three channels together
//! (the definition of the Mitsuba reference script's `nrmse`, so figures
//! are comparable); `per_channel[c]` uses channel `c` alone. Dividing by the
//! mean rather than per pixel keeps dark pixels from dominating.

use super::{Image, ImageError};

/// Relative RMSE of an image against a reference (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelativeRmse {
    /// Over all three channels.
    pub overall: f64,
    /// R, G, B separately; `None` for a channel the reference is zero in
    /// over the compared pixels, where a relative error means nothing.
    pub per_channel: [Option<f64>; 3],
    /// Pixels compared (those the mask selects).
    pub pixels: usize,
    /// The reference's mean over those pixels and the three channels.
    pub reference_mean: f64,
    /// `Σ a / Σ b` over the compared pixels and channels: a bias shows as a
    /// ratio away from 1 by more than the noise.
    pub mean_ratio: f64,
    /// The overall figure expected from the image's own noise alone,
    /// `sqrt(mean(variance)) / mean(b)` from its variance channel (`None`
    /// without one). If the reference is noisy too, the expected overall
    /// figure is `sqrt(expected² + reference_noise²)`.
    pub expected_from_variance: Option<f64>,
}

/// Relative RMSE of `image` against `reference` over the pixels where
/// `mask` is true (all pixels without a mask). The reference's mean over
/// those pixels must be positive.
pub fn relative_rmse(
    image: &Image,
    reference: &Image,
    mask: Option<&[bool]>,
) -> Result<RelativeRmse, ImageError> {
    if (image.width(), image.height()) != (reference.width(), reference.height()) {
        return Err(ImageError::invalid(
            "reference",
            format!(
                "{}×{} differs from the image's {}×{}",
                reference.width(),
                reference.height(),
                image.width(),
                image.height()
            ),
        ));
    }
    if let Some(m) = mask
        && m.len() != image.rgb().len()
    {
        return Err(ImageError::invalid(
            "mask",
            format!("{} entries for {} pixels", m.len(), image.rgb().len()),
        ));
    }
    let (mut squared, mut sum, mut pixels) = ([0.0f64; 3], [0.0f64; 3], 0usize);
    let mut image_sum = 0.0;
    let mut variance = 0.0;
    for (i, (a, b)) in image.rgb().iter().zip(reference.rgb()).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        pixels += 1;
        variance += image.variance().map_or(0.0, |v| f64::from(v[i]));
        for c in 0..3 {
            let d = f64::from(a[c]) - f64::from(b[c]);
            squared[c] += d * d;
            sum[c] += f64::from(b[c]);
            image_sum += f64::from(a[c]);
        }
    }
    let total: f64 = sum.iter().sum();
    if pixels == 0 || total.is_nan() || total <= 0.0 {
        return Err(ImageError::invalid(
            "reference",
            "the compared pixels have no positive mean",
        ));
    }
    let n = pixels as f64;
    let mean = total / (3.0 * n);
    let overall = (squared.iter().sum::<f64>() / (3.0 * n)).sqrt() / mean;
    let per_channel =
        [0, 1, 2].map(|c| (sum[c] > 0.0).then(|| (squared[c] / n).sqrt() / (sum[c] / n)));
    // `variance` is already the mean over channels, so its pixel mean is
    // the mean over pixels and channels, like the squared errors.
    let expected_from_variance = image.variance().map(|_| (variance / n).sqrt() / mean);
    Ok(RelativeRmse {
        overall,
        per_channel,
        pixels,
        reference_mean: mean,
        mean_ratio: image_sum / total,
        expected_from_variance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(rgb: Vec<[f32; 3]>) -> Image {
        Image::from_parts(rgb.len() as u32, 1, rgb, None).expect("valid")
    }

    #[test]
    fn matches_the_definition() {
        let reference = image(vec![[1.0, 2.0, 3.0], [3.0, 2.0, 1.0]]);
        let a = image(vec![[1.5, 2.0, 3.0], [3.0, 2.0, 0.5]]);
        let e = relative_rmse(&a, &reference, None).expect("comparable");
        // Squared errors 0.25 + 0.25 over 6 values; mean of the reference 2.
        assert!((e.overall - (0.5f64 / 6.0).sqrt() / 2.0).abs() < 1e-12);
        assert!((e.per_channel[0].unwrap() - (0.25f64 / 2.0).sqrt() / 2.0).abs() < 1e-12);
        assert_eq!(e.per_channel[1], Some(0.0));
        // A channel the reference is black in has no relative error.
        let red = image(vec![[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
        let e = relative_rmse(&red, &red, None).expect("comparable");
        assert_eq!(e.per_channel, [Some(0.0), None, None]);
        assert_eq!(e.pixels, 2);
        // Both sum to 12.
        assert!((e.mean_ratio - 1.0).abs() < 1e-12);
        assert_eq!(e.expected_from_variance, None);
        let noisy = Image::from_parts(2, 1, a.rgb().to_vec(), Some(vec![0.25, 0.75])).expect("ok");
        let expected = relative_rmse(&noisy, &reference, None)
            .expect("ok")
            .expected_from_variance;
        assert_eq!(expected, Some(0.5f64.sqrt() / 2.0));
        assert_eq!(
            relative_rmse(&reference, &reference, None)
                .expect("ok")
                .overall,
            0.0
        );

        let masked = relative_rmse(&a, &reference, Some(&[false, true])).expect("ok");
        assert!((masked.overall - (0.25f64 / 3.0).sqrt() / 2.0).abs() < 1e-12);
    }

    #[test]
    fn incomparable_inputs_are_errors() {
        let a = image(vec![[1.0; 3]; 2]);
        let black = image(vec![[0.0; 3]; 2]);
        assert!(relative_rmse(&a, &black, None).is_err());
        assert!(relative_rmse(&a, &image(vec![[1.0; 3]; 3]), None).is_err());
        assert!(relative_rmse(&a, &a, Some(&[true])).is_err());
        assert!(relative_rmse(&a, &a, Some(&[false, false])).is_err());
    }
}
