//! False colour for scalar images (e.g. a render's relative standard
//! error): a perceptually ordered dark-blue → green → yellow ramp, the
//! viridis colour map of van der Walt & Smith (matplotlib, 2015; public
//! domain), sampled at nine points and interpolated linearly in sRGB.
//! Readers of the map see "brighter = larger" also in greyscale.

/// sRGB codes at `t = 0, 1/8, …, 1`.
const ANCHORS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 44, 122],
    [59, 81, 139],
    [44, 113, 142],
    [33, 144, 141],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];

/// The colour of `t`, clamped to `[0, 1]` (NaN maps to 0).
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (ANCHORS.len() - 1) as f64;
    let i = (x.floor() as usize).min(ANCHORS.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|c| {
        let (a, b) = (f64::from(ANCHORS[i][c]), f64::from(ANCHORS[i + 1][c]));
        (a + (b - a) * f).round() as u8
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_and_clamping() {
        assert_eq!(viridis(0.0), ANCHORS[0]);
        assert_eq!(viridis(1.0), ANCHORS[8]);
        assert_eq!(viridis(-3.0), ANCHORS[0]);
        assert_eq!(viridis(7.0), ANCHORS[8]);
        assert_eq!(viridis(f64::NAN), ANCHORS[0]);
        assert_eq!(viridis(0.5), ANCHORS[4]);
        // Green rises monotonically: the ramp is ordered.
        let greens: Vec<u8> = (0..=16).map(|k| viridis(f64::from(k) / 16.0)[1]).collect();
        assert!(greens.windows(2).all(|w| w[0] <= w[1]), "{greens:?}");
    }
}
