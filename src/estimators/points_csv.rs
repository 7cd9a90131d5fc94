//! CSV exchange for irradiance queries: `x,y,z,nx,ny,nz` rows in,
//! `x,y,z,r,g,b` rows out (W/m²).
//!
//! Input rules: an optional header line (a first line none of whose fields is
//! a number); blank lines and lines starting with `#` are skipped; every other
//! line must hold exactly six finite numbers and a non-zero normal, or the
//! whole file is rejected with the 1-based line number.

use std::io::{self, Write};

use crate::render::{PointDoc, QueryPoint, RenderError};
use crate::scene::meter::IrradianceMeter;

/// Parses a points file; see the module docs for the accepted format. The
/// points are returned as written (each checked), so they reach an
/// estimator exactly as the same numbers in a request would.
pub fn parse_points(text: &str) -> Result<Vec<PointDoc>, RenderError> {
    let mut points = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let row = raw.trim();
        if row.is_empty() || row.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = row.split(',').map(str::trim).collect();
        if line == 1 && fields.iter().all(|f| f.parse::<f64>().is_err()) {
            continue;
        }
        let row_error = |reason: String| RenderError::PointsRow { line, reason };
        if fields.len() != 6 {
            return Err(row_error(format!(
                "expected 6 fields x,y,z,nx,ny,nz, found {}",
                fields.len()
            )));
        }
        let mut values = [0.0; 6];
        for (k, (field, value)) in fields.iter().zip(values.iter_mut()).enumerate() {
            *value = field
                .parse::<f64>()
                .map_err(|_| row_error(format!("field {} ({field:?}) is not a number", k + 1)))?;
        }
        let point = PointDoc {
            position: [values[0], values[1], values[2]],
            normal: [values[3], values[4], values[5]],
        };
        point.point().map_err(|e| row_error(e.to_string()))?;
        points.push(point);
    }
    Ok(points)
}

/// Writes one `x,y,z,nx,ny,nz` row per point, with a header: the input
/// format of [`parse_points`], so points a study drew can be queried again
/// (by this tool or another renderer).
pub fn write_points(out: &mut dyn Write, points: &[QueryPoint]) -> io::Result<()> {
    writeln!(out, "x,y,z,nx,ny,nz")?;
    for point in points {
        let (p, n) = (point.position(), point.normal());
        writeln!(out, "{},{},{},{},{},{}", p.x, p.y, p.z, n.x, n.y, n.z)?;
    }
    Ok(())
}

/// Writes one `x,y,z,r,g,b` row per point, with a header; with `std_dev`,
/// three more columns `se_r,se_g,se_b` hold the standard errors. Numbers
/// use Rust's shortest round-trip formatting.
pub fn write_irradiance(
    out: &mut dyn Write,
    points: &[PointDoc],
    irradiance: &[[f64; 3]],
    std_dev: Option<&[[f64; 3]]>,
) -> io::Result<()> {
    write!(out, "x,y,z,r,g,b")?;
    if std_dev.is_some() {
        write!(out, ",se_r,se_g,se_b")?;
    }
    writeln!(out)?;
    for (i, (point, e)) in points.iter().zip(irradiance).enumerate() {
        let p = point.position;
        write!(out, "{},{},{},{},{},{}", p[0], p[1], p[2], e[0], e[1], e[2])?;
        if let Some(s) = std_dev.and_then(|s| s.get(i)) {
            write!(out, ",{},{},{}", s[0], s[1], s[2])?;
        }
        writeln!(out)?;
    }
    Ok(())
}

/// Writes one `meter,r,g,b,se_r,se_g,se_b` row per irradiance meter (its
/// id, its value and standard error, W/m²), with a header.
pub fn write_meters(
    out: &mut dyn Write,
    meters: &[IrradianceMeter],
    values: &[([f64; 3], [f64; 3])],
) -> io::Result<()> {
    writeln!(out, "meter,r,g,b,se_r,se_g,se_b")?;
    for (meter, (e, s)) in meters.iter().zip(values) {
        // An id is the user's text: quoted as CSV quotes fields.
        let id = meter.id.replace('"', "\"\"");
        writeln!(
            out,
            "\"{id}\",{},{},{},{},{},{}",
            e[0], e[1], e[2], s[0], s[1], s[2]
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn written_points_read_back_exactly() {
        let points = [
            QueryPoint::new(DVec3::new(0.1, -2.5e-7, 3.0), DVec3::new(0.3, 0.4, -0.5)).unwrap(),
            QueryPoint::new(DVec3::ZERO, DVec3::Y).unwrap(),
        ];
        let mut text = Vec::new();
        write_points(&mut text, &points).unwrap();
        let read = parse_points(std::str::from_utf8(&text).unwrap()).unwrap();
        assert_eq!(read.len(), points.len());
        for (a, b) in read.iter().map(|p| p.point().unwrap()).zip(&points) {
            assert_eq!(a.position(), b.position());
            // Normals are normalised again when read: equal to the last ulp.
            assert!((a.normal() - b.normal()).length() < 1e-15);
        }
    }

    #[test]
    fn header_comments_and_blank_lines_are_skipped() {
        let text = "x,y,z,nx,ny,nz\n0,0,0,0,0,2\n\n# a comment\n 1.5, -1 ,2e-1,1,0,0\n";
        let points = parse_points(text).unwrap();
        assert_eq!(points.len(), 2);
        assert_eq!(points[0].normal, [0.0, 0.0, 2.0]);
        assert_eq!(points[0].point().unwrap().normal(), DVec3::Z);
        assert_eq!(points[1].position, [1.5, -1.0, 0.2]);
    }

    #[test]
    fn bad_rows_report_their_line() {
        let cases = [
            ("0,0,0,0,0,1\n0,0,0,0,1\n", 2, "expected 6 fields"),
            ("0,0,0,0,0,1\n\n0,0,zero,0,1,0\n", 3, "field 3"),
            ("0,0,0,0,0,0\n", 1, "non-zero length"),
            ("x,y,z,nx,ny,nz\n0,0,0,NaN,0,1\n", 2, "finite"),
        ];
        for (text, line, needle) in cases {
            match parse_points(text) {
                Err(RenderError::PointsRow { line: l, reason }) => {
                    assert_eq!(l, line, "{text:?}");
                    assert!(reason.contains(needle), "{reason}");
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn output_has_one_row_per_point() {
        let points = parse_points("1,2,3,0,0,1\n").unwrap();
        let mut out = Vec::new();
        write_irradiance(&mut out, &points, &[[0.5, 1.0, 2.0]], Some(&[[0.25; 3]])).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "x,y,z,r,g,b,se_r,se_g,se_b\n1,2,3,0.5,1,2,0.25,0.25,0.25\n"
        );
    }
}
