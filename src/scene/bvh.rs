//! Bounding volume hierarchy built with the binned surface area heuristic
//! (Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies",
//! 2007) and traversed front to back.
//!
//! The tree only knows primitive bounds; callers intersect primitives in a
//! closure, so the same tree type serves triangles and analytic shapes.
//! Nodes are 32 bytes (two per cache line): f32 bounds rounded outwards, so
//! they always contain the f64 primitives, and slab tests done in f64 so the
//! ray itself is never rounded.
//!
//! A 4-wide variant (binary tree collapsed, four f32 boxes per SIMD test) was
//! tried and measured 12–17 % slower than this scalar binary traversal in an
//! in-process A/B on the bundled scenes (docs/BENCHMARKS.md), so it was dropped.

use glam::DVec3;

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

    /// Entry distance of the ray into this box if it enters before `t_max`.
    #[inline(always)]
    fn hit(&self, o: DVec3, inv: DVec3, t_max: f64) -> Option<f64> {
        // `inv` is finite (see `traverse`), so no 0·∞ = NaN can arise when
        // the origin lies on a slab plane of a ray parallel to it.
        let x0 = (self.min[0] as f64 - o.x) * inv.x;
        let x1 = (self.max[0] as f64 - o.x) * inv.x;
        let y0 = (self.min[1] as f64 - o.y) * inv.y;
        let y1 = (self.max[1] as f64 - o.y) * inv.y;
        let z0 = (self.min[2] as f64 - o.z) * inv.z;
        let z1 = (self.max[2] as f64 - o.z) * inv.z;
        let near = x0.min(x1).max(y0.min(y1)).max(z0.min(z1)).max(0.0);
        // Widen the exit by a few ulps so rounding never drops a hit that
        // lies exactly on the box (pbrt-v4's robust slab test).
        let far = x0.max(x1).min(y0.max(y1)).min(z0.max(z1)) * (1.0 + 1e-14);
        (near <= far.min(t_max)).then_some(near)
    }
}

/// SAH cost of one traversal step relative to one primitive test.
const TRAVERSAL_COST: f64 = 1.0;
const BINS: usize = 16;
/// Leaves larger than this are split even if the SAH prefers a leaf.
const MAX_LEAF: usize = 8;
/// Depth bound; the traversal stack is sized from it.
const MAX_DEPTH: usize = 60;

pub struct Bvh {
    nodes: Vec<Node>,
}

/// Bytes of one BVH node.
pub const NODE_BYTES: usize = std::mem::size_of::<Node>();

impl Bvh {
    /// Bytes the tree holds on the heap.
    pub fn heap_bytes(&self) -> u64 {
        (self.nodes.capacity() * NODE_BYTES) as u64
    }

    /// Builds a tree over `bounds`. Returns the tree and the build order:
    /// leaf ranges index positions in `order`, and `order[i]` is the index in
    /// `bounds` of the primitive at position `i`. Callers store their
    /// primitives permuted by `order`.
    pub fn build(bounds: &[Aabb]) -> (Bvh, Vec<u32>) {
        let mut order: Vec<u32> = (0..bounds.len() as u32).collect();
        if bounds.is_empty() {
            return (Bvh { nodes: Vec::new() }, order);
        }
        let centroids: Vec<DVec3> = bounds.iter().map(Aabb::centroid).collect();
        let mut nodes = vec![Node::new(&Aabb::EMPTY, 0, 0)];
        nodes.reserve(2 * bounds.len());
        let mut todo = vec![(0usize, 0usize, bounds.len(), 0usize)];
        while let Some((index, start, end, depth)) = todo.pop() {
            let range = &mut order[start..end];
            let bb = range
                .iter()
                .fold(Aabb::EMPTY, |b, &i| b.union(bounds[i as usize]));
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
        (Bvh { nodes }, order)
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
        let Some(root) = self.nodes.first() else {
            return false;
        };
        // Zero components become ±1e-300 so the inverse is huge but finite.
        let inv = dir
            .map(|c| if c == 0.0 { 1e-300f64.copysign(c) } else { c })
            .recip();
        if root.hit(origin, inv, *t_max).is_none() {
            return false;
        }
        let mut stack = [0u32; MAX_DEPTH + 2];
        let mut top = 0usize;
        let mut node = root;
        loop {
            if node.count > 0 {
                let first = node.first as usize;
                for i in first..first + node.count as usize {
                    if visit(i, t_max) {
                        return true;
                    }
                }
            } else {
                let left = node.first as usize;
                let (a, b) = (&self.nodes[left], &self.nodes[left + 1]);
                match (a.hit(origin, inv, *t_max), b.hit(origin, inv, *t_max)) {
                    (Some(ta), Some(tb)) => {
                        let (near, far) = if ta <= tb {
                            (left, left + 1)
                        } else {
                            (left + 1, left)
                        };
                        stack[top] = far as u32;
                        top += 1;
                        node = &self.nodes[near];
                        continue;
                    }
                    (Some(_), None) => {
                        node = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop, skipping nodes that now start beyond the closest hit.
            loop {
                if top == 0 {
                    return false;
                }
                top -= 1;
                let candidate = &self.nodes[stack[top] as usize];
                if candidate.hit(origin, inv, *t_max).is_some() {
                    node = candidate;
                    break;
                }
            }
        }
    }
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
        assert!(bvh.nodes.len() < 2 * boxes.len());
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
        assert!(bvh.nodes.iter().all(|n| n.count as usize <= MAX_LEAF));
        let mut seen = 0;
        bvh.closest(DVec3::splat(-1.0), DVec3::ONE.normalize(), 1e9, |_, _| {
            seen += 1;
            None
        });
        assert_eq!(seen, 100);
    }
}
