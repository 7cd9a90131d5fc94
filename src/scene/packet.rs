//! The (up to four) triangles of a BVH leaf tested at once in f32 SIMD
//! lanes, as a conservative filter in front of the exact f64 test.
//!
//! The f64 Möller–Trumbore test (`shape::TriangleAccel::intersect`) decides
//! every hit; the packet only rules out lanes that it provably misses, and
//! names the lanes it provably hits. The f32 quantities are compared with
//! margins that bound their rounding error (and the f64 test's), so a lane
//! the f64 test would hit is never dropped and the hits found are the same,
//! bit for bit, as without the packet.
//!
//! The rows live in an array of their own, in the tree's build order, so
//! that the traversal prefetches a waiting leaf's 48 bytes per triangle (the
//! f64 forms, 72 bytes each, are read only for the lanes the filter keeps).
//!
//! The margins and why they are conservative: `docs/math.md` §18.

use std::ops::Range;

use glam::{DVec3, Vec4};

use super::bvh::{round_down, round_up};

/// Relative margin of the f32 quantities, 16·2⁻²⁴ (`docs/math.md` §18).
const ERROR: f32 = 1.0 / 1_048_576.0;
/// Absolute margin, far above the rounding of subnormal results.
const TINY: f32 = 1e-30;
/// Rays and scenes beyond these magnitudes skip the filter (every lane is a
/// candidate): below them no f32 product of the test can overflow (the
/// largest, `L²·S`, stays below 2¹¹⁰) or lose its margin to underflow.
const MAX_COORDINATE: f64 = (1u64 << 30) as f64;
const DIRECTION_RANGE: std::ops::RangeInclusive<f64> = 1.0 / 1_048_576.0..=1_048_576.0;

/// Every triangle's f32 rows, leaf by leaf: the leaf of `n` triangles at
/// positions `first..first + n` occupies entries `first..first + n`, read as
/// [`ROWS`] rows of `n` f32 lanes each (v₀ x, y, z, e₁ x, y, z, e₂ x, y, z,
/// the two margin factors `L` and `L·(2|v₀|₁ + L)`, and a spare row). A row
/// loads as four lanes; the lanes past `n` read what follows (one padding
/// entry at the end) and are masked.
#[derive(Clone, Debug, Default)]
pub(crate) struct LeafRows {
    rows: Vec<[f32; ROWS]>,
}

/// f32 rows per triangle: v₀, e₁, e₂, the margin factors, and one spare row
/// (48 bytes, a multiple of a 16-byte lane group).
pub(crate) const ROWS: usize = 12;

/// A ray splatted across lanes for [`LeafRows::test`], or
/// `None` when it lies outside the filter's safe range.
pub(crate) struct PacketRay(Option<Lanes>);

struct Lanes {
    origin: [Vec4; 3],
    dir: [Vec4; 3],
    /// `|o|₁` and `|d|₁`.
    origin_norm: f32,
    dir_norm: f32,
}

impl PacketRay {
    /// `extent`: the largest coordinate magnitude of the scene's triangles.
    #[inline]
    pub fn new(origin: DVec3, dir: DVec3, extent: f64) -> PacketRay {
        let origin_norm = origin.abs().element_sum();
        let dir_norm = dir.abs().element_sum();
        let safe = origin_norm <= MAX_COORDINATE
            && extent <= MAX_COORDINATE
            && DIRECTION_RANGE.contains(&dir_norm);
        PacketRay(safe.then(|| Lanes {
            origin: origin.to_array().map(|c| Vec4::splat(c as f32)),
            dir: dir.to_array().map(|c| Vec4::splat(c as f32)),
            origin_norm: origin_norm as f32,
            dir_norm: dir_norm as f32,
        }))
    }
}

fn cross(a: &[Vec4; 3], b: &[Vec4; 3]) -> [Vec4; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: &[Vec4; 3], b: &[Vec4; 3]) -> Vec4 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl LeafRows {
    /// The rows of `vertices` (in the tree's build order), laid out for the
    /// tree's leaf ranges (each of at most four positions).
    pub fn new(vertices: &[[DVec3; 3]], leaves: impl Iterator<Item = Range<usize>>) -> Self {
        let mut rows = vec![[0.0f32; ROWS]; vertices.len() + 1];
        let mut hist = [0usize; 5];
        for leaf in leaves {
            hist[leaf.len()] += 1;
            let n = leaf.len();
            let block = rows[leaf.clone()].as_flattened_mut();
            for (k, p) in vertices[leaf].iter().enumerate() {
                let (v0, e1, e2) = (p[0], p[1] - p[0], p[2] - p[0]);
                let edge = e1.abs().element_sum().max(e2.abs().element_sum());
                let own = edge * (2.0 * v0.abs().element_sum() + edge);
                let values = [v0, e1, e2]
                    .into_iter()
                    .flat_map(|v| v.to_array())
                    .map(|x| x as f32);
                // Rounded up: both are margins' factors.
                let bounds = [round_up(edge), round_up(own)];
                for (r, x) in values.chain(bounds).enumerate() {
                    block[r * n + k] = x;
                }
            }
        }
        if std::env::var_os("BMC_HIST").is_some() {
            eprintln!("leaf sizes {hist:?}");
        }
        LeafRows { rows }
    }

    /// One entry per triangle position (the traversal prefetches a leaf's).
    pub fn entries(&self) -> &[[f32; ROWS]] {
        &self.rows[..self.rows.len() - 1]
    }

    /// Bytes held on the heap.
    pub fn heap_bytes(&self) -> u64 {
        (self.rows.capacity() * std::mem::size_of::<[f32; ROWS]>()) as u64
    }

    /// Two lane masks over the leaf's triangles (lane `k` is position
    /// `leaf.start + k`): those the exact f64 test might hit with
    /// `0 < t < t_max` (it certainly misses the others), and among them those
    /// it certainly hits.
    #[inline(always)]
    pub fn test(&self, leaf: &Range<usize>, ray: &PacketRay, t_max: f64) -> LaneMasks {
        let n = leaf.len();
        let lanes = (1u32 << n) - 1;
        let Some(ray) = &ray.0 else {
            return LaneMasks {
                maybe: lanes,
                sure: 0,
                sure_before: [f32::INFINITY; 4],
            };
        };
        let block = self.rows[leaf.start..leaf.end + 1].as_flattened();
        let row = |r: usize| Vec4::from_slice(&block[r * n..r * n + 4]);
        let (v0, e1, e2) = (
            [row(0), row(1), row(2)],
            [row(3), row(4), row(5)],
            [row(6), row(7), row(8)],
        );
        let s = [
            ray.origin[0] - v0[0],
            ray.origin[1] - v0[1],
            ray.origin[2] - v0[2],
        ];
        let p = cross(&ray.dir, &e2);
        let det = dot(&e1, &p);
        let u = dot(&s, &p);
        let q = cross(&s, &e1);
        let v = dot(&ray.dir, &q);
        let t = dot(&e2, &q);

        // L·S with S = 4|o|₁ + 2|v₀|₁ + L ≥ 2(|s|₁ + |o|₁) + L.
        let (edge, own) = (row(9), row(10));
        let edge_scale = edge * (4.0 * ray.origin_norm) + own;
        let margin = edge_scale * (ERROR * ray.dir_norm) + Vec4::splat(TINY);
        let t_margin = edge_scale * edge * ERROR + Vec4::splat(TINY);

        // Signs taken so that a hit has u, v, t ≥ 0 and u + v ≤ |det|.
        let flip = det.cmplt(Vec4::ZERO);
        let (u, v, t) = (
            Vec4::select(flip, -u, u),
            Vec4::select(flip, -v, v),
            Vec4::select(flip, -t, t),
        );
        let det = det.abs();
        // A lane is dropped only where det's sign is certain and a
        // condition fails by more than its margin. NaN compares false and
        // keeps the lane.
        let far = Vec4::splat(round_up(t_max));
        let miss = det.cmpgt(margin)
            & (u.cmplt(-margin)
                | v.cmplt(-margin)
                | (u + v).cmpgt(det + margin * 3.0)
                | t.cmplt(-t_margin)
                | t.cmpgt(far * (det + margin) + t_margin));
        // A lane is a sure hit where every condition holds by more than its
        // margin (NaN compares false and leaves it unsure).
        let near = Vec4::splat(round_down(t_max));
        let hit = det.cmpgt(margin)
            & u.cmpgt(margin)
            & v.cmpgt(margin)
            & (u + v).cmplt(det - margin * 3.0)
            & t.cmpgt(t_margin)
            & t.cmplt(near * (det - margin) - t_margin);
        // A sure hit's exact t = (t ± mₜ) / (|det| ± m) is below this bound
        // (the f32 quotient rounded, then scaled up by 2⁻²⁰ to cover it).
        let before = (t + t_margin) / (det - margin) * FAR_SCALE;
        LaneMasks {
            maybe: !miss.bitmask() & lanes,
            sure: hit.bitmask() & lanes,
            sure_before: before.to_array(),
        }
    }
}

/// Lane bit masks from [`LeafRows::test`]; `sure` ⊆ `maybe`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LaneMasks {
    pub maybe: u32,
    pub sure: u32,
    /// Per lane of `sure`, an upper bound of the exact hit distance
    /// (meaningless for the other lanes).
    pub sure_before: [f32; 4],
}

/// Scales a positive f32 up past a few roundings of its own (2⁻²⁰ ≫ 2⁻²⁴).
const FAR_SCALE: f32 = 1.0 + 1.0 / 1_048_576.0;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    use crate::scene::shape::{Triangle, TriangleAccel};

    /// One leaf of `triangles`.
    fn leaf(triangles: &[[DVec3; 3]]) -> LeafRows {
        LeafRows::new(triangles, std::iter::once(0..triangles.len()))
    }

    fn intersect_triangle(
        p: &[DVec3; 3],
        o: DVec3,
        d: DVec3,
        t_max: f64,
    ) -> Option<(f64, f64, f64)> {
        let t = Triangle {
            p: *p,
            shape: 0,
            primitive: 0,
            normals: u32::MAX,
        };
        TriangleAccel::new(&t).intersect(o, d, t_max)
    }

    fn random_unit(rng: &mut impl RngExt) -> DVec3 {
        loop {
            let v = DVec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - 1.0;
            if let Some(u) = (v.length_squared() <= 1.0)
                .then(|| v.try_normalize())
                .flatten()
            {
                return u;
            }
        }
    }

    /// Rays aimed at the hardest places for a rounded test: vertices and
    /// points on or next to edges, at grazing angles, from origins on the
    /// triangle's plane and far away, over many scales; every f64 hit must
    /// remain a candidate, and every sure hit must be an f64 hit.
    #[test]
    fn the_filter_agrees_with_the_exact_test() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let (mut hits, mut wrong) = (0, 0);
        for k in 0..40_000 {
            let size = 10f64.powi(rng.random_range(-6..=4));
            let offset = random_unit(&mut rng) * 10f64.powi(rng.random_range(-3..=6));
            let tris: Vec<[DVec3; 3]> = (0..4)
                .map(|_| {
                    let base = offset + random_unit(&mut rng) * size * rng.random::<f64>();
                    let a = random_unit(&mut rng) * size;
                    // Some slivers: the third vertex almost on the first edge.
                    let b = if k % 7 == 0 {
                        a * rng.random::<f64>() + random_unit(&mut rng) * size * 1e-7
                    } else {
                        random_unit(&mut rng) * size
                    };
                    [base, base + a, base + b]
                })
                .collect();
            let target_tri = &tris[k % 4];
            let (w1, w2) = match k % 4 {
                0 => (0.0, rng.random::<f64>()), // on an edge
                1 => (1.0, 0.0),                 // a vertex
                2 => {
                    let u = rng.random::<f64>();
                    (u, 1.0 - u) // the far edge
                }
                _ => (rng.random::<f64>() * 0.5, rng.random::<f64>() * 0.5),
            };
            let [p0, p1, p2] = *target_tri;
            let target = p0
                + (p1 - p0) * w1
                + (p2 - p0) * w2
                + random_unit(&mut rng) * size * 1e-9 * rng.random::<f64>();
            let normal = (p1 - p0).cross(p2 - p0).normalize_or_zero();
            let dir = if k % 3 == 0 {
                // Grazing: almost in the triangle's plane.
                (random_unit(&mut rng).reject_from(normal) + normal * 1e-6 * rng.random::<f64>())
                    .normalize_or(DVec3::X)
            } else {
                random_unit(&mut rng)
            };
            let distance = size * 10f64.powi(rng.random_range(-9..=4));
            let origin = target - dir * distance;
            let t_max = [f64::INFINITY, distance * (1.0 + 1e-12), distance * 2.0][k % 3];
            let ray = PacketRay::new(origin, dir, 1e7);
            let masks = leaf(&tris).test(&(0..4), &ray, t_max);
            for (lane, tri) in tris.iter().enumerate() {
                let bit = 1 << lane;
                if let Some((t, _, _)) = intersect_triangle(tri, origin, dir, t_max) {
                    hits += 1;
                    if masks.maybe & bit == 0 {
                        wrong += 1;
                        eprintln!("ray {k}: lane {lane} hit but filtered out");
                    }
                    if masks.sure & bit != 0 && t > f64::from(masks.sure_before[lane]) {
                        wrong += 1;
                        eprintln!("ray {k}: lane {lane} hit beyond its bound");
                    }
                } else if masks.sure & bit != 0 {
                    wrong += 1;
                    eprintln!("ray {k}: lane {lane} missed but called sure");
                }
            }
        }
        assert_eq!(wrong, 0);
        assert!(hits > 10_000, "{hits} hits: the rays must test something");
    }

    #[test]
    fn the_filter_drops_clear_misses_and_unused_lanes() {
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let packet = leaf(&[tri, tri]);
        let ray = |o: DVec3| PacketRay::new(o, -DVec3::Z, 10.0);
        let masks = |maybe, sure| (maybe, sure);
        let packet = |leaf: Range<usize>, ray: &PacketRay, t_max| {
            let m = packet.test(&leaf, ray, t_max);
            (m.maybe, m.sure)
        };
        // Through the middle: both used lanes, surely; the two holes never.
        let middle = ray(DVec3::new(0.2, 0.2, 1.0));
        assert_eq!(packet(0..2, &middle, 9.0), masks(0b11, 0b11));
        let bound = leaf(&[tri, tri]).test(&(0..2), &middle, 9.0).sure_before;
        assert!(
            bound[..2].iter().all(|&b| (1.0..1.0 + 1e-5).contains(&b)),
            "{bound:?}"
        );
        // Beside it, behind the origin, or beyond t_max: none.
        assert_eq!(
            packet(0..2, &ray(DVec3::new(0.8, 0.8, 1.0)), 9.0),
            masks(0, 0)
        );
        assert_eq!(
            packet(0..2, &ray(DVec3::new(0.2, 0.2, -1.0)), 9.0),
            masks(0, 0)
        );
        assert_eq!(packet(0..2, &middle, 0.5), masks(0, 0));
        // Exactly through an edge: possible, not sure.
        let edge = ray(DVec3::new(0.5, 0.5, 1.0));
        assert_eq!(packet(0..2, &edge, 9.0), masks(0b11, 0));
        // Outside the safe range every used lane is possible, none sure.
        let far = PacketRay::new(DVec3::new(0.2, 0.2, 1e12), -DVec3::Z, 10.0);
        assert_eq!(packet(0..2, &far, 9.0), masks(0b11, 0));
    }
}
