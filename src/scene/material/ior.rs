//! Named indices of refraction of dielectric media, as scene files name
//! them in `int_ior` and `ext_ior` (Mitsuba 3's names). Values at about
//! 589 nm and 0–20 °C, from E. Hecht, "Optics", 4th edition, the source
//! Mitsuba cites; scenes that name a medium get the same number as there.

/// The index of air, Mitsuba's default exterior medium.
pub const AIR: f64 = 1.000277;

/// The index of BK7 glass, Mitsuba's default interior of dielectrics.
pub const BK7: f64 = 1.5046;

/// The index of polypropylene, Mitsuba's default coating of plastics.
pub const POLYPROPYLENE: f64 = 1.49;

/// `(name, index)`, the names lower case.
pub const NAMED_MEDIA: [(&str, f64); 23] = [
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", AIR),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", POLYPROPYLENE),
    ("bk7", BK7),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

/// The index of the medium `name` (any case), or `None` if it has none here.
pub fn named_ior(name: &str) -> Option<f64> {
    let name = name.trim().to_ascii_lowercase();
    NAMED_MEDIA
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, ior)| ior)
}

/// The names [`named_ior`] knows, for error messages.
pub fn media_names() -> String {
    let names: Vec<&str> = NAMED_MEDIA.iter().map(|(n, _)| *n).collect();
    names.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_in_any_case_and_unknown_ones_do_not() {
        assert_eq!(named_ior("BK7"), Some(1.5046));
        assert_eq!(named_ior("water"), Some(1.333));
        assert_eq!(named_ior(" Air "), Some(1.000277));
        assert_eq!(named_ior("unobtainium"), None);
        assert!(media_names().contains("diamond"));
        for (name, ior) in NAMED_MEDIA {
            assert!(ior >= 1.0 && name == name.to_ascii_lowercase());
        }
    }
}
