//! Mitsuba 3's named conductors (`material` of `conductor` and
//! `roughconductor`: `Au`, `Ag`, `Cu`, `Al`, …) as RGB complex indices of
//! refraction `η + i k`. Mitsuba keeps measured spectra and, in its RGB
//! variants, integrates each against the CIE 1931 matching functions into
//! linear sRGB, clamping negatives; these are the values it renders with
//! (Mitsuba 3.9.1, printed by `docs/validation/mitsuba_named_metals.py`),
//! so a scene naming a metal looks here as it does there. `none` is
//! Mitsuba's perfect mirror.

/// `(name, η, k)` per RGB channel; names as Mitsuba spells them.
pub const NAMED_METALS: [(&str, [f64; 3], [f64; 3]); 38] = [
    (
        "a-C",
        [2.94405, 2.22714, 1.96816],
        [0.887465, 0.799299, 0.81529],
    ),
    (
        "Ag",
        [0.155276, 0.116728, 0.138388],
        [4.82835, 3.12222, 2.1469],
    ),
    ("Al", [1.6575, 0.880405, 0.521244], [9.22381, 6.2695, 4.837]),
    (
        "AlAs",
        [3.6053, 3.23294, 2.21632],
        [0.000679437, 0.0, 0.00751271],
    ),
    ("AlSb", [0.0, 4.13937, 4.66925], [0.0, 0.0940091, 1.30057]),
    (
        "Au",
        [0.143036, 0.375307, 1.44205],
        [3.983, 2.38556, 1.60336],
    ),
    (
        "Be",
        [4.18501, 3.18503, 2.78406],
        [3.83547, 3.01012, 2.86899],
    ),
    ("Cr", [4.36967, 2.91651, 1.6549], [5.20655, 4.23131, 3.7547]),
    ("CsI", [2.1449, 1.70232, 1.66243], [0.0, 0.0, 0.0]),
    (
        "Cu",
        [0.201005, 0.92375, 1.10222],
        [3.91326, 2.45305, 2.14209],
    ),
    (
        "Cu2O",
        [3.55177, 2.94987, 2.75188],
        [0.114207, 0.193897, 0.606134],
    ),
    (
        "CuO",
        [3.24754, 2.44781, 2.21022],
        [0.52109, 0.570031, 0.722179],
    ),
    ("d-C", [2.70872, 2.31883, 2.2289], [0.0, 0.0, 0.0]),
    (
        "Hg",
        [2.39894, 1.44003, 0.90957],
        [6.32759, 4.37192, 3.42176],
    ),
    (
        "HgTe",
        [4.77904, 3.2312, 2.6599],
        [1.63161, 1.58081, 1.72929],
    ),
    (
        "Ir",
        [3.0863, 2.08219, 1.61791],
        [5.59215, 4.06709, 3.26731],
    ),
    (
        "K",
        [0.0640432, 0.0464098, 0.0381849],
        [2.1042, 1.34894, 0.913126],
    ),
    (
        "Li",
        [0.265791, 0.195618, 0.220949],
        [3.54015, 2.31112, 1.66861],
    ),
    (
        "MgO",
        [2.08958, 1.65072, 1.59488],
        [4.3327e-12, 0.0, 2.49865e-11],
    ),
    (
        "Mo",
        [4.48397, 3.52513, 2.77631],
        [4.11144, 3.42083, 3.15061],
    ),
    (
        "Na_palik",
        [0.0602694, 0.0561409, 0.0619884],
        [3.17927, 2.11249, 1.57904],
    ),
    (
        "Nb",
        [3.42007, 2.79009, 2.39563],
        [3.44139, 2.73767, 2.57975],
    ),
    (
        "Ni_palik",
        [2.3673, 1.66337, 1.46708],
        [4.49881, 3.05015, 2.34544],
    ),
    (
        "Rh",
        [2.58579, 1.86022, 1.55426],
        [6.78226, 4.70299, 3.97607],
    ),
    (
        "Se",
        [4.05831, 2.84294, 2.82085],
        [0.75405, 0.638444, 0.521808],
    ),
    (
        "SiC",
        [3.17234, 2.52597, 2.47937],
        [7.53766e-07, 0.0, 1.01925e-05],
    ),
    ("SnTe", [4.52425, 1.98164, 1.28159], [0.0, 0.0, 0.0]),
    (
        "Ta",
        [2.06272, 2.39294, 2.62793],
        [2.40836, 1.74149, 1.94703],
    ),
    (
        "Te",
        [7.39023, 4.4821, 2.63711],
        [3.25602, 3.52706, 3.29205],
    ),
    ("ThF4", [1.83071, 1.44223, 1.38765], [0.0, 0.0, 0.0]),
    (
        "TiC",
        [3.70053, 2.83742, 2.58229],
        [3.26564, 2.35159, 2.17279],
    ),
    (
        "TiN",
        [1.64845, 1.15052, 1.37982],
        [3.36833, 1.9435, 1.10207],
    ),
    (
        "TiO2",
        [3.45661, 2.80174, 2.90517],
        [0.000105265, 0.0, 0.000652887],
    ),
    (
        "VC",
        [3.65757, 2.75274, 2.53267],
        [3.0683, 2.19869, 1.96319],
    ),
    (
        "V_palik",
        [4.27758, 3.51295, 2.76107],
        [3.4913, 2.88945, 3.11152],
    ),
    (
        "VN",
        [2.8656, 2.11919, 1.94009],
        [3.03224, 2.05612, 1.61631],
    ),
    (
        "W",
        [4.37082, 3.30025, 2.99841],
        [3.50064, 2.60487, 2.27323],
    ),
    ("none", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
];

/// `(η, k)` of the metal `name` (exact spelling, as Mitsuba), or `None`.
pub fn named_metal(name: &str) -> Option<([f64; 3], [f64; 3])> {
    NAMED_METALS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|&(_, eta, k)| (eta, k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::fresnel;

    fn normal_reflectance(name: &str) -> [f64; 3] {
        let (eta, k) = named_metal(name).expect("known");
        [0, 1, 2].map(|c| fresnel::conductor(1.0, eta[c], k[c]))
    }

    #[test]
    fn metals_have_their_colours() {
        let gold = normal_reflectance("Au");
        assert!(gold[0] > gold[1] && gold[1] > gold[2], "{gold:?}");
        let copper = normal_reflectance("Cu");
        assert!(copper[0] > copper[2], "{copper:?}");
        let silver = normal_reflectance("Ag");
        assert!(silver.iter().all(|&r| r > 0.9), "{silver:?}");
        assert_eq!(normal_reflectance("none"), [1.0; 3]);
        assert!(named_metal("au").is_none() && named_metal("Unobtainium").is_none());
        // Mitsuba 3.9.1's `conductor` with material Au reflects
        // (0.966069, 0.801277, 0.329045) at cos θ = 0.8.
        let (eta, k) = named_metal("Au").unwrap();
        let at_08 = [0, 1, 2].map(|c| fresnel::conductor(0.8, eta[c], k[c]));
        for (ours, theirs) in at_08.iter().zip([0.966_069, 0.801_277, 0.329_045]) {
            assert!((ours - theirs).abs() < 2e-5, "{at_08:?}");
        }
    }
}
