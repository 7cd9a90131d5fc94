//! Crafted files and uploads, as an attacker or a careless client sends
//! them: small files whose headers claim large payloads, archive bombs,
//! `<ref>` doubling, and the multipart bodies that carry them.

use serde_json::{Value, json};

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

/// The boundary of [`multipart`] bodies.
pub const BOUNDARY: &str = "bmc-test-boundary-7f3a";

/// A `multipart/form-data` body (boundary [`BOUNDARY`]) of `parts`:
/// (field name, file name, content type, bytes).
pub fn multipart(parts: &[(&str, Option<&str>, &str, Vec<u8>)]) -> Vec<u8> {
    let mut body = Vec::new();
    for (name, filename, content_type, bytes) in parts {
        body.extend(format!("--{BOUNDARY}\r\n").bytes());
        let disposition = match filename {
            Some(f) => format!("form-data; name=\"{name}\"; filename=\"{f}\""),
            None => format!("form-data; name=\"{name}\""),
        };
        body.extend(format!("Content-Disposition: {disposition}\r\n").bytes());
        body.extend(format!("Content-Type: {content_type}\r\n\r\n").bytes());
        body.extend(bytes);
        body.extend(b"\r\n");
    }
    body.extend(format!("--{BOUNDARY}--\r\n").bytes());
    body
}

/// A JSON scene `hostile` of one `shape` (material `m`, diffuse) seen by an
/// 8² camera, with `extra` top-level fields replacing its own, uploaded as
/// a [`multipart`] body with `assets` (file name, bytes).
pub fn scene_upload(shape: Value, extra: Value, assets: Vec<(&str, Vec<u8>)>) -> Vec<u8> {
    let mut doc = json!({
        "name": "hostile",
        "materials": [{"id": "m", "type": "diffuse", "reflectance": 0.5}],
        "shapes": [shape],
        "camera": {"fov": 40, "width": 8, "height": 8,
                   "origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}
    });
    for (key, value) in extra.as_object().expect("extra is an object") {
        doc[key] = value.clone();
    }
    let mut parts = vec![(
        "scene",
        Some("hostile.json"),
        "application/json",
        doc.to_string().into_bytes(),
    )];
    for (name, bytes) in assets {
        parts.push(("asset", Some(name), "application/octet-stream", bytes));
    }
    multipart(&parts)
}

/// A baseline JPEG of `width × height` texels by its header, 8×8 by its
/// data (about 600 bytes).
pub fn jpeg_claiming(width: u16, height: u16) -> Vec<u8> {
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new(&mut bytes)
        .encode(&[128u8; 8 * 8 * 3], 8, 8, image::ExtendedColorType::Rgb8)
        .expect("in memory");
    // The baseline frame header: FF C0, length, precision, height, width.
    let sof = bytes
        .windows(2)
        .position(|w| w == [0xFF, 0xC0])
        .expect("a baseline frame");
    bytes[sof + 5..sof + 7].copy_from_slice(&height.to_be_bytes());
    bytes[sof + 7..sof + 9].copy_from_slice(&width.to_be_bytes());
    bytes
}

/// A binary PLY of one triangle whose header first declares an element
/// `junk` of 10¹¹ entries without properties (244 bytes).
pub fn ply_with_junk_element() -> Vec<u8> {
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement junk 100000000000\n\
        element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    ply.extend([0u8; 36]);
    ply.extend([3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    ply
}

/// A Mitsuba scene whose BSDF `b{levels}` doubles `levels` times through
/// `<ref>`s: a few lines, 2^levels plugins if copied.
pub fn ref_doubling_xml(levels: usize) -> String {
    let mut body = String::from(r#"<bsdf type="diffuse" id="b0"/>"#);
    for n in 1..=levels {
        body += &format!(
            r#"<bsdf type="blendbsdf" id="b{n}"><ref id="b{m}"/><ref id="b{m}"/></bsdf>"#,
            m = n - 1
        );
    }
    format!(
        r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm">
        <integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
        {body}<shape type="rectangle"><ref id="b{levels}"/></shape></scene>"#
    )
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
}
