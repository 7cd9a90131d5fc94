//! Test support shared by the unit tests next to the code and the
//! integration tests in `tests/it`: the bundled-scene fixtures, the one
//! statistical assertion and a maker of crafted gzip streams (archive
//! bombs). Not part of the service's interface.
//!
//! # Tolerance policy
//! A Monte Carlo result is compared with another or with a reference by
//! [`agrees`]: `|a − b| ≤ k·se + rel·|b|`, where `se` is the standard error of
//! the difference (the two errors combined in quadrature when both are
//! random) and
//! - `k = 4` by default: a correct estimator fails a single check with
//!   probability 6·10⁻⁵, so a suite of a few hundred such checks stays green;
//!   `k = 5` where one test makes many comparisons at once;
//! - `rel` is zero for unbiased comparisons. It is non-zero only where a
//!   method has a known, bounded bias (interpolation from cache records, BMC
//!   glossy weights interpolated in `θ_r`), and then the test says which
//!   bias and how large it is allowed to be.
//!
//! Deterministic quantities (closed forms, identities) are compared with
//! plain absolute or relative bounds instead.

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use crate::cache::Record;
use crate::render::{Rgb, Transport};
use crate::scene::Scene;

/// A small valid scene document: a diffuse unit rectangle under a constant
/// white sky, seen by an 8² camera.
pub const TINY_SCENE: &str = r#"{
    "materials": [{"id": "white", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
    "shapes": [{"type": "rectangle", "material": "white"}],
    "environment": {"type": "constant", "radiance": [1, 1, 1]},
    "camera": {"type": "perspective", "fov": 40, "origin": [0, 0, 3], "target": [0, 0, 0],
               "up": [0, 1, 0], "width": 8, "height": 8}
}"#;

/// Whether `a` and `b` agree within `sigmas` standard errors `se` of their
/// difference plus a relative allowance `rel·|b|` (module docs).
pub fn agrees(a: f64, b: f64, se: f64, sigmas: f64, rel: f64) -> bool {
    (a - b).abs() <= sigmas * se + rel * b.abs()
}

/// The bundled Cornell box, with its camera resized to `side`² pixels.
pub fn cornell(side: u32) -> Transport {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(dir.join("cornell-box.json")).expect("bundled scene");
    let mut doc: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    doc["camera"]["width"] = side.into();
    doc["camera"]["height"] = side.into();
    let scene = Scene::from_json_str(&doc.to_string(), &dir, &dir).expect("loads");
    Transport::new(Arc::new(scene))
}

/// A ground plane (z = 0, facing +z) under a square occluder of half-side
/// ¼ at height 1, lit by a point light of intensity 4 at height 2 above the
/// origin, whose shadow on the ground is the square of half-side ½, and by
/// a constant sky of radiance `sky` (none if 0).
pub fn occluded_ground(sky: f64) -> Transport {
    let mut doc = serde_json::json!({
        "materials": [{"id": "grey", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
        "shapes": [
            {"type": "rectangle", "material": "grey", "to_world": [{"scale": [10, 10, 1]}]},
            {"type": "rectangle", "material": "grey",
             "to_world": [{"scale": [0.25, 0.25, 1]}, {"translate": [0, 0, 1]}]}
        ],
        "lights": [{"type": "point", "position": [0, 0, 2], "intensity": [4, 4, 4]}],
        "camera": {"type": "perspective", "fov": 30, "origin": [0, 0, 6],
                   "target": [0, 0, 0], "up": [0, 1, 0], "width": 4, "height": 4}
    });
    if sky > 0.0 {
        doc["environment"] = serde_json::json!({"type": "constant", "radiance": [sky, sky, sky]});
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::from_json_str(&doc.to_string(), dir, dir).expect("loads");
    Transport::new(Arc::new(scene))
}

/// A record holding `irradiance` at `position` within `radius`, with no
/// variance and no gradients (the place and value a test needs).
pub fn flat_record(position: DVec3, normal: DVec3, irradiance: Rgb, radius: f64) -> Record {
    Record {
        position,
        normal,
        irradiance,
        variance: Rgb::BLACK,
        radius,
        rotation_gradient: [DVec3::ZERO; 3],
        translation_gradient: [DVec3::ZERO; 3],
    }
}

/// A standard normal variate by Box–Muller (`1 − U` keeps the logarithm finite).
pub fn standard_normal<R: rand::Rng + ?Sized>(rng: &mut R) -> f64 {
    use rand::RngExt;
    let (u, v): (f64, f64) = (rng.random(), rng.random());
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Runs `f` on a rayon pool of `threads` threads (results must not depend on it).
pub fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}

/// A two-part EXR file: a 1×1 depth part in front of an RGB part that
/// claims `side`² pixels (ZIP-compressed, 16 rows a chunk), as an
/// attacker's file would: written 2×2, then its data window, chunk count
/// and offset table are made to agree with the claim, every chunk pointing
/// at the one written (the pixels are never there). Decoders read the RGB
/// part; its table is `8·side/16` bytes (100 KB for 200000²).
pub fn two_part_exr(side: i32) -> Vec<u8> {
    use exr::prelude::*;
    let part = |name: &str, size: usize, channels: &[&str], encoding| {
        let channels = channels
            .iter()
            .map(|c| AnyChannel::new(*c, FlatSamples::F32(vec![0.5; size * size])))
            .collect();
        Layer::new(
            (size, size),
            LayerAttributes::named(name),
            encoding,
            AnyChannels::sort(channels),
        )
    };
    let zip16 = Encoding {
        compression: Compression::ZIP16,
        ..Encoding::UNCOMPRESSED
    };
    let layers = vec![
        part("depth", 1, &["Z"], Encoding::UNCOMPRESSED),
        part("beauty", 2, &["R", "G", "B"], zip16),
    ];
    let mut bytes = Vec::new();
    let attributes = ImageAttributes::new(IntegerBounds::from_dimensions((2, 2)));
    exr::image::Image::from_layers(attributes, layers)
        .write()
        .to_buffered(std::io::Cursor::new(&mut bytes))
        .expect("encodes");
    // The value of the RGB part's (the second) attribute `name` of `kind`.
    let value_at = |bytes: &[u8], name: &str, kind: &str| {
        let tag = [name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat();
        bytes
            .windows(tag.len())
            .enumerate()
            .filter(|(_, w)| *w == tag.as_slice())
            .map(|(i, _)| i + tag.len() + 4)
            .nth(1)
            .expect("both parts have it")
    };
    // `box2i`: x_min, y_min, x_max, y_max as i32.
    let window = value_at(&bytes, "dataWindow", "box2i");
    bytes[window + 8..window + 12].copy_from_slice(&(side - 1).to_le_bytes());
    bytes[window + 12..window + 16].copy_from_slice(&(side - 1).to_le_bytes());
    let chunks = (side as u64).div_ceil(16);
    let count = value_at(&bytes, "chunkCount", "int");
    bytes[count..count + 4].copy_from_slice(&(chunks as i32).to_le_bytes());
    // The offset tables follow the headers: one entry for each part, the
    // first pointing just past both.
    let u64_at = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().expect("8 bytes"));
    let table = (0..bytes.len() - 16)
        .find(|&i| u64_at(i) == i as u64 + 16)
        .expect("the offset tables");
    let shift = 8 * (chunks - 1);
    let mut out = bytes[..table].to_vec();
    out.extend((u64_at(table) + shift).to_le_bytes());
    for _ in 0..chunks {
        out.extend((u64_at(table + 8) + shift).to_le_bytes());
    }
    out.extend(&bytes[table + 16..]);
    out
}

/// A Mitsuba `serialized` file (version 4) of one single-precision mesh
/// of `vertices` vertices, all at the origin, and `triangles` triangles
/// `[0, 0, 0]`: zeros, which compress about a thousandfold, so a few
/// kilobytes claim what takes hundreds of megabytes once inflated.
pub fn serialized_mesh(vertices: u64, triangles: u64) -> Vec<u8> {
    use std::io::Write;
    let mut out = 0x041Cu16.to_le_bytes().to_vec();
    out.extend(4u16.to_le_bytes());
    let mut z = flate2::write::ZlibEncoder::new(out, flate2::Compression::best());
    z.write_all(&0u32.to_le_bytes()).expect("in memory");
    z.write_all(b"bomb\0").expect("in memory");
    z.write_all(&vertices.to_le_bytes()).expect("in memory");
    z.write_all(&triangles.to_le_bytes()).expect("in memory");
    let zeros = vec![0u8; 1 << 20];
    let mut left = 12 * (vertices + triangles);
    while left > 0 {
        let n = left.min(zeros.len() as u64) as usize;
        z.write_all(&zeros[..n]).expect("in memory");
        left -= n as u64;
    }
    let mut out = z.finish().expect("in memory");
    out.extend(0u64.to_le_bytes());
    out.extend(1u32.to_le_bytes());
    out
}

/// One gzip member holding `before`, then `zeros_mib` mebibytes of zeros,
/// then `after`: the long run of zeros of a crafted archive (a bomb), made
/// without deflating the zeros one by one. A mebibyte of zeros is deflated
/// once and its blocks repeated: each part is deflated by a fresh
/// compressor ending on a full flush, so it is byte-aligned and refers to
/// nothing before it, and the parts' blocks chain into one valid stream.
/// 8 GiB of zeros take about 8 MB, the most deflate packs them.
pub fn gzip_with_zeros(before: &[u8], zeros_mib: u64, after: &[u8]) -> Vec<u8> {
    use flate2::{Compress, Compression, Crc, FlushCompress, Status};
    let deflated = |bytes: &[u8], last: bool| {
        let flush = if last {
            FlushCompress::Finish
        } else {
            FlushCompress::Full
        };
        let mut compress = Compress::new(Compression::best(), false);
        let mut out = Vec::new();
        loop {
            out.reserve(1 << 16);
            let read = compress.total_in() as usize;
            let status = compress
                .compress_vec(&bytes[read..], &mut out, flush)
                .expect("deflates");
            let flushed = compress.total_in() as usize == bytes.len() && out.len() < out.capacity();
            if status == Status::StreamEnd || (!last && flushed) {
                return out;
            }
        }
    };
    let crc_of = |bytes: &[u8]| {
        let mut crc = Crc::new();
        crc.update(bytes);
        crc
    };
    let zeros = vec![0u8; 1 << 20];
    let (zeros_deflated, zeros_crc) = (deflated(&zeros, false), crc_of(&zeros));
    // The gzip header: deflate, no flags, no time, unknown system.
    let mut gz = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0xff];
    gz.extend(deflated(before, false));
    let mut crc = crc_of(before);
    for _ in 0..zeros_mib {
        gz.extend(&zeros_deflated);
        crc.combine(&zeros_crc);
    }
    gz.extend(deflated(after, true));
    crc.combine(&crc_of(after));
    let length = before.len() as u64 + (zeros_mib << 20) + after.len() as u64;
    gz.extend(crc.sum().to_le_bytes());
    // ISIZE: the length modulo 2³².
    gz.extend((length as u32).to_le_bytes());
    gz
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gzip_with_zeros_inflates_to_its_parts() {
        use std::io::Read;
        let gz = gzip_with_zeros(b"head", 3, b"tail");
        assert!(gz.len() < 8 << 10, "{} bytes", gz.len());
        let mut inflated = Vec::new();
        flate2::read::GzDecoder::new(gz.as_slice())
            .read_to_end(&mut inflated)
            .unwrap();
        assert_eq!(inflated.len(), 8 + (3 << 20));
        assert_eq!(&inflated[..4], b"head");
        assert!(inflated[4..4 + (3 << 20)].iter().all(|b| *b == 0));
        assert_eq!(&inflated[4 + (3 << 20)..], b"tail");
    }

    #[test]
    fn agreement_is_within_sigmas_plus_the_relative_allowance() {
        assert!(agrees(10.0, 10.3, 0.1, 4.0, 0.0));
        assert!(!agrees(10.0, 10.5, 0.1, 4.0, 0.0));
        assert!(agrees(10.0, 10.5, 0.1, 4.0, 0.02));
    }
}
