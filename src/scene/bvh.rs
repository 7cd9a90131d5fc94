//! Bounding volume hierarchy built with the binned surface area heuristic
//! (Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies",
//! 2007) and traversed front to back.
//!
//! The tree only knows primitive bounds; callers intersect primitives in a
//! closure, so the same tree type serves triangles and analytic shapes.
//! The binary SAH tree is collapsed into 4-wide nodes whose f32 boxes
//! (rounded strictly outwards, so they contain the f64 primitives) are tested
//! four at a time with SIMD; the slab test pads for the rounding of the ray
//! origin, so it never misses a box the exact f64 ray enters.

use glam::{DVec3, Vec4};

/// Axis-aligned box in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    pub fn from_points(points: &[DVec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, p| b.grow(*p))
    }

    pub fn grow(self, p: DVec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn centroid(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    /// Half the surface area (all the SAH needs is ratios).
    fn half_area(&self) -> f64 {
        let d = (self.max - self.min).max(DVec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// Interior nodes have `count == 0` and children `first`, `first + 1`;
/// leaves hold primitives `first .. first + count` in build order.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Node {
    min: [f32; 3],
    first: u32,
    max: [f32; 3],
    count: u32,
}

/// Largest f32 strictly below `x`. Strictly, so that a ray whose origin lies
/// exactly on a primitive's bounding plane and whose direction component is
/// (±)0 is still inside the padded slab whatever the sign of that zero.
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 >= x { f.next_down() } else { f }
}

/// Smallest f32 strictly above `x`.
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) <= x { f.next_up() } else { f }
}

impl Node {
    fn new(b: &Aabb, first: u32, count: u32) -> Node {
        Node {
            min: [
                round_down(b.min.x),
                round_down(b.min.y),
                round_down(b.min.z),
            ],
            first,
            max: [round_up(b.max.x), round_up(b.max.y), round_up(b.max.z)],
            count,
        }
    }

    fn half_area(&self) -> f32 {
        let d = [0, 1, 2].map(|a| self.max[a] - self.min[a]);
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }
}

/// Four children's boxes in structure-of-arrays form, tested together with
/// 4-wide SIMD (glam's `Vec4` is SSE on x86-64, NEON on aarch64). A slot
/// with `count > 0` is a leaf holding primitives `child .. child + count`;
/// otherwise `child` indexes `Bvh::nodes`. Unused slots have both bounds
/// at +∞, which no ray can enter.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Wide {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    child: [u32; 4],
    count: [u32; 4],
}

impl Wide {
    const EMPTY: Wide = Wide {
        lo: [Vec4::INFINITY; 3],
        hi: [Vec4::INFINITY; 3],
        child: [0; 4],
        count: [0; 4],
    };

    fn set(&mut self, slot: usize, n: &Node) {
        for a in 0..3 {
            self.lo[a][slot] = n.min[a];
            self.hi[a][slot] = n.max[a];
        }
    }
}

/// Per-ray constants of the conservative f32 slab test.
///
/// The f64 origin rounded to f32 is off by at most 2⁻²⁴·|o|; testing the
/// lower planes from `o + pad` and the upper planes from `o − pad` with
/// `pad = 2⁻²²·max|o|` widens every box by more than that, so a box the exact
/// ray enters is never missed. Zero direction components are replaced by
/// ±1e-30 so the inverse is finite and no 0·∞ = NaN arises.
struct RayConsts {
    lo_origin: [Vec4; 3],
    hi_origin: [Vec4; 3],
    inv: [Vec4; 3],
}

impl RayConsts {
    fn new(origin: DVec3, dir: DVec3) -> Self {
        let pad = origin.abs().max_element() * (1.0 / 4_194_304.0) + 1e-30;
        let axis = |a: usize| {
            let d = dir[a];
            let d = if d.abs() < 1e-30 {
                1e-30f64.copysign(d)
            } else {
                d
            };
            (
                Vec4::splat(round_up(origin[a] + pad)),
                Vec4::splat(round_down(origin[a] - pad)),
                Vec4::splat((1.0 / d) as f32),
            )
        };
        let (x, y, z) = (axis(0), axis(1), axis(2));
        Self {
            lo_origin: [x.0, y.0, z.0],
            hi_origin: [x.1, y.1, z.1],
            inv: [x.2, y.2, z.2],
        }
    }

    /// Entry distances of the four boxes and the mask of those entered
    /// before `t_max`.
    #[inline(always)]
    fn hit(&self, n: &Wide, t_max: f32) -> (Vec4, u32) {
        let mut near = Vec4::ZERO;
        let mut far = Vec4::splat(t_max);
        for a in 0..3 {
            let t0 = (n.lo[a] - self.lo_origin[a]) * self.inv[a];
            let t1 = (n.hi[a] - self.hi_origin[a]) * self.inv[a];
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        // A few ulps of slack for the rounding of the products (pbrt-v4's
        // robust slab test scales the exit by 1 + 2γ₃).
        let mask = near.cmple(far * (1.0 + 1e-6)).bitmask();
        (near, mask)
    }
}

/// SAH cost of one traversal step relative to one primitive test.
const TRAVERSAL_COST: f64 = 1.0;
const BINS: usize = 16;
/// Leaves larger than this are split even if the SAH prefers a leaf.
const MAX_LEAF: usize = 8;
/// Depth bound of the binary build; the wide tree is at most this deep too.
const MAX_DEPTH: usize = 60;
/// Traversal stack: at most 3 entries pushed per level plus the root's 4.
const STACK: usize = 3 * MAX_DEPTH + 4;

/// A 4-wide BVH: built as a binary SAH tree, then collapsed so each node
/// holds up to four children (the largest-area grandchildren are pulled up).
pub struct Bvh {
    nodes: Vec<Wide>,
    bounds: Aabb,
}

impl Bvh {
    /// Builds a tree over `bounds`. Returns the tree and the build order:
    /// leaf ranges index positions in `order`, and `order[i]` is the index in
    /// `bounds` of the primitive at position `i`. Callers store their
    /// primitives permuted by `order`.
    pub fn build(bounds: &[Aabb]) -> (Bvh, Vec<u32>) {
        let mut order: Vec<u32> = (0..bounds.len() as u32).collect();
        if bounds.is_empty() {
            let empty = Bvh {
                nodes: Vec::new(),
                bounds: Aabb::EMPTY,
            };
            return (empty, order);
        }
        let centroids: Vec<DVec3> = bounds.iter().map(Aabb::centroid).collect();
        let mut nodes = vec![Node::new(&Aabb::EMPTY, 0, 0)];
        nodes.reserve(2 * bounds.len());
        let mut todo = vec![(0usize, 0usize, bounds.len(), 0usize)];
        let mut total = Aabb::EMPTY;
        while let Some((index, start, end, depth)) = todo.pop() {
            let range = &mut order[start..end];
            let bb = range
                .iter()
                .fold(Aabb::EMPTY, |b, &i| b.union(bounds[i as usize]));
            if index == 0 {
                total = bb;
            }
            let split = if depth >= MAX_DEPTH {
                None
            } else {
                split(range, bounds, &centroids, &bb)
            };
            match split {
                Some(mid) => {
                    let left = nodes.len();
                    nodes.push(Node::new(&Aabb::EMPTY, 0, 0));
                    nodes.push(Node::new(&Aabb::EMPTY, 0, 0));
                    nodes[index] = Node::new(&bb, left as u32, 0);
                    todo.push((left, start, start + mid, depth + 1));
                    todo.push((left + 1, start + mid, end, depth + 1));
                }
                None => nodes[index] = Node::new(&bb, start as u32, (end - start) as u32),
            }
        }
        let bvh = Bvh {
            nodes: collapse(&nodes),
            bounds: total,
        };
        (bvh, order)
    }

    /// Bounds of everything in the tree (empty box if no primitives).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Number of 4-wide nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Closest-hit traversal. `intersect(i, t_max)` tests primitive position
    /// `i` and returns its hit distance if it is below `t_max`; the caller
    /// records whatever else it needs. Returns the closest distance found.
    #[inline]
    pub fn closest(
        &self,
        origin: DVec3,
        dir: DVec3,
        mut t_max: f64,
        mut intersect: impl FnMut(usize, f64) -> Option<f64>,
    ) -> Option<f64> {
        let mut found = None;
        self.traverse(origin, dir, &mut t_max, |i, t_max| {
            if let Some(t) = intersect(i, *t_max) {
                *t_max = t;
                found = Some(t);
            }
            false
        });
        found
    }

    /// Any-hit traversal: true as soon as `intersect(i, t_max)` reports a hit.
    #[inline]
    pub fn any(
        &self,
        origin: DVec3,
        dir: DVec3,
        mut t_max: f64,
        mut intersect: impl FnMut(usize, f64) -> bool,
    ) -> bool {
        self.traverse(origin, dir, &mut t_max, |i, t_max| intersect(i, *t_max))
    }

    /// Front-to-back traversal; `visit` may shrink `t_max` and returns true to stop.
    #[inline(always)]
    fn traverse(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_max: &mut f64,
        mut visit: impl FnMut(usize, &mut f64) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let ray = RayConsts::new(origin, dir);
        // Finite, so the +∞ entry distance of unused slots always exceeds it.
        let limit_of = |t: f64| round_up(t).min(f32::MAX);
        let mut limit = limit_of(*t_max);
        // Entries: (child, count, entry distance); count > 0 marks a leaf.
        let mut stack = [(0u32, 0u32, 0f32); STACK];
        stack[0] = (0, 0, 0.0);
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (child, count, near) = stack[top];
            if near > limit {
                continue;
            }
            if count > 0 {
                for i in child as usize..(child + count) as usize {
                    if visit(i, t_max) {
                        return true;
                    }
                }
                limit = limit_of(*t_max);
                continue;
            }
            let node = &self.nodes[child as usize];
            let (dist, mut mask) = ray.hit(node, limit);
            // Push hit children far to near so the nearest is popped first.
            let mut hits = [(0f32, 0usize); 4];
            let mut n = 0;
            while mask != 0 {
                let slot = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let d = dist[slot];
                let mut j = n;
                while j > 0 && hits[j - 1].0 < d {
                    hits[j] = hits[j - 1];
                    j -= 1;
                }
                hits[j] = (d, slot);
                n += 1;
            }
            for &(d, slot) in &hits[..n] {
                stack[top] = (node.child[slot], node.count[slot], d);
                top += 1;
            }
        }
        false
    }
}

/// Collapses a binary tree (root at 0) into 4-wide nodes (root at 0).
fn collapse(binary: &[Node]) -> Vec<Wide> {
    let mut wide = vec![Wide::EMPTY];
    if binary[0].count > 0 {
        wide[0].set(0, &binary[0]);
        wide[0].child[0] = binary[0].first;
        wide[0].count[0] = binary[0].count;
        return wide;
    }
    let mut todo = vec![(0usize, 0usize)];
    while let Some((b, w)) = todo.pop() {
        let first = binary[b].first as usize;
        let mut kids = vec![first, first + 1];
        while kids.len() < 4 {
            let widest = kids
                .iter()
                .enumerate()
                .filter(|(_, k)| binary[**k].count == 0)
                .max_by(|a, b| {
                    binary[*a.1]
                        .half_area()
                        .total_cmp(&binary[*b.1].half_area())
                });
            let Some((j, &k)) = widest else { break };
            let grand = binary[k].first as usize;
            kids.swap_remove(j);
            kids.extend([grand, grand + 1]);
        }
        let mut node = Wide::EMPTY;
        for (slot, &k) in kids.iter().enumerate() {
            node.set(slot, &binary[k]);
            if binary[k].count > 0 {
                node.child[slot] = binary[k].first;
                node.count[slot] = binary[k].count;
            } else {
                node.child[slot] = wide.len() as u32;
                wide.push(Wide::EMPTY);
                todo.push((k, wide.len() - 1));
            }
        }
        wide[w] = node;
    }
    wide
}

/// Binned SAH split of `range` (reordered in place); `None` makes a leaf.
/// Returns the number of primitives going left.
fn split(range: &mut [u32], bounds: &[Aabb], centroids: &[DVec3], bb: &Aabb) -> Option<usize> {
    let count = range.len();
    if count <= 1 {
        return None;
    }
    let cb = range
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.grow(centroids[i as usize]));
    let extent = cb.max - cb.min;
    let leaf_cost = count as f64;
    let parent_area = bb.half_area().max(f64::MIN_POSITIVE);
    let mut best: Option<(f64, usize, usize)> = None; // cost, axis, bins left
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let scale = BINS as f64 / extent[axis];
        let bin_of = |i: u32| {
            (((centroids[i as usize][axis] - cb.min[axis]) * scale) as usize).min(BINS - 1)
        };
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        for &i in range.iter() {
            let b = bin_of(i);
            bin_bounds[b] = bin_bounds[b].union(bounds[i as usize]);
            bin_count[b] += 1;
        }
        // Sweep from the right to get the right-side areas, then from the left.
        let mut right_area = [0.0; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        let mut right_count = [0usize; BINS];
        for b in (1..BINS).rev() {
            acc = acc.union(bin_bounds[b]);
            n += bin_count[b];
            right_area[b] = acc.half_area();
            right_count[b] = n;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for b in 1..BINS {
            acc = acc.union(bin_bounds[b - 1]);
            n += bin_count[b - 1];
            if n == 0 || right_count[b] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (acc.half_area() * n as f64 + right_area[b] * right_count[b] as f64)
                    / parent_area;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    match best {
        Some((cost, axis, bins_left)) if cost < leaf_cost || count > MAX_LEAF => {
            let scale = BINS as f64 / extent[axis];
            let mid = partition(range, |i| {
                (((centroids[i as usize][axis] - cb.min[axis]) * scale) as usize).min(BINS - 1)
                    < bins_left
            });
            Some(mid)
        }
        Some(_) => None,
        // All centroids coincide: only an arbitrary split can bound the leaf size.
        None if count > MAX_LEAF => Some(count / 2),
        None => None,
    }
}

/// Moves the elements satisfying `left` to the front; returns how many.
fn partition(range: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let mut mid = 0;
    for j in 0..range.len() {
        if left(range[j]) {
            range.swap(mid, j);
            mid += 1;
        }
    }
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let c = DVec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
                let h = DVec3::new(rng.random(), rng.random(), rng.random()) * 0.3;
                Aabb {
                    min: c - h,
                    max: c + h,
                }
            })
            .collect()
    }

    /// Exact f64 ray/box entry distance, for brute force comparison.
    fn box_hit(b: &Aabb, o: DVec3, d: DVec3, t_max: f64) -> Option<f64> {
        let inv = d.recip();
        let t0 = (b.min - o) * inv;
        let t1 = (b.max - o) * inv;
        let near = t0.min(t1).max_element().max(0.0);
        let far = t0.max(t1).min_element().min(t_max);
        (near <= far).then_some(near)
    }

    #[test]
    fn traversal_agrees_with_brute_force() {
        let boxes = random_boxes(500, 7);
        let (bvh, order) = Bvh::build(&boxes);
        assert!(bvh.node_count() < 2 * boxes.len());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
        for k in 0..300 {
            // Finite and infinite ray extents take different paths.
            let t_max = if k % 2 == 0 { 1e9 } else { f64::INFINITY };
            let o = DVec3::new(rng.random(), rng.random(), rng.random()) * 12.0 - 1.0;
            let d = (DVec3::new(rng.random(), rng.random(), rng.random()) - 0.5).normalize();
            // "Primitives" are the boxes themselves.
            let expected = boxes
                .iter()
                .filter_map(|b| box_hit(b, o, d, t_max))
                .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))));
            let got = bvh.closest(o, d, t_max, |i, t_max| {
                box_hit(&boxes[order[i] as usize], o, d, t_max).filter(|&t| t < t_max)
            });
            assert_eq!(got, expected);
            let any = bvh.any(o, d, t_max, |i, t_max| {
                box_hit(&boxes[order[i] as usize], o, d, t_max).is_some()
            });
            assert_eq!(any, expected.is_some());
        }
    }

    #[test]
    fn axis_parallel_rays_on_a_slab_plane_still_hit() {
        let boxes = vec![
            Aabb {
                min: DVec3::ZERO,
                max: DVec3::ONE,
            },
            Aabb {
                min: DVec3::splat(3.0),
                max: DVec3::splat(4.0),
            },
        ];
        let (bvh, _) = Bvh::build(&boxes);
        // Origin x = 0 lies on the first box's slab plane; dir.x = 0.
        let hits = |o: DVec3, d: DVec3| bvh.any(o, d, 1e9, |_, _| true);
        assert!(hits(DVec3::new(0.0, 5.0, 0.5), -DVec3::Y));
        assert!(hits(DVec3::new(-0.0, 5.0, 0.5), DVec3::new(0.0, -1.0, 0.0)));
        assert!(hits(DVec3::new(1.0, 5.0, 1.0), -DVec3::Y));
        assert!(hits(DVec3::new(1.0, 0.5, -2.0), DVec3::Z));
        assert!(!hits(DVec3::new(1.5, 0.5, -2.0), DVec3::Z));
    }

    #[test]
    fn identical_primitives_still_give_small_leaves() {
        let boxes = vec![
            Aabb {
                min: DVec3::ZERO,
                max: DVec3::ONE
            };
            100
        ];
        let (bvh, order) = Bvh::build(&boxes);
        assert_eq!(order.len(), 100);
        assert!(
            bvh.nodes
                .iter()
                .all(|n| n.count.iter().all(|&c| c as usize <= MAX_LEAF))
        );
        let mut seen = 0;
        bvh.closest(DVec3::splat(-1.0), DVec3::ONE.normalize(), 1e9, |_, _| {
            seen += 1;
            None
        });
        assert_eq!(seen, 100);
    }
}
