//! Bounding volume hierarchy built with the binned surface area heuristic
//! (Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies",
//! 2007), traversed front to back for the closest hit and in the children's
//! slot order for any hit (sorting them cost shadow rays 6 %,
//! docs/BENCHMARKS.md "Ray tracing").
//!
//! The tree only knows primitive bounds; callers intersect primitives in a
//! closure, so the same tree type serves triangles and analytic shapes.
//! The binary tree is collapsed to four children per node, whose boxes are
//! tested at once in f32 SIMD lanes. Boxes are rounded outwards and the
//! slab distances made conservative (see [`SlabRay`]), so the traversal
//! never skips a primitive the exact f64 ray hits; primitives themselves are
//! intersected in f64 by the caller.

mod build;

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

/// A child slot of a [`Node`] that holds primitives has this bit set; the
/// next four bits are the primitive count and the low 27 bits the first
/// primitive's position. Other slots hold the index of a node.
const LEAF: u32 = 1 << 31;
const LEAF_COUNT_SHIFT: u32 = 27;
const LEAF_FIRST_MASK: u32 = (1 << LEAF_COUNT_SHIFT) - 1;

/// The primitive positions of a leaf slot (`code & LEAF != 0`).
#[inline(always)]
fn leaf_range(code: u32) -> std::ops::Range<usize> {
    let first = (code & LEAF_FIRST_MASK) as usize;
    first..first + ((code & !LEAF) >> LEAF_COUNT_SHIFT) as usize
}

/// Four children's boxes, one SIMD lane each, in f32 rounded outwards so
/// they always contain the f64 primitives (two cache lines).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    /// min x, max x, min y, max y, min z, max z of the four children; unused
    /// slots are empty boxes (min +∞, max −∞), which no ray enters.
    bounds: [[f32; 4]; 6],
    child: [u32; 4],
}

impl Node {
    const EMPTY: Node = Node {
        bounds: [
            [f32::INFINITY; 4],
            [f32::NEG_INFINITY; 4],
            [f32::INFINITY; 4],
            [f32::NEG_INFINITY; 4],
            [f32::INFINITY; 4],
            [f32::NEG_INFINITY; 4],
        ],
        child: [0; 4],
    };

    fn set_bounds(&mut self, slot: usize, b: &Aabb) {
        for axis in 0..3 {
            self.bounds[2 * axis][slot] = round_down(b.min[axis]);
            self.bounds[2 * axis + 1][slot] = round_up(b.max[axis]);
        }
    }

    /// Which of the four children the ray enters before `t_max`, as a bit
    /// mask, and the entry distances (a lower bound of the exact ones).
    /// `PARALLEL_AXES` compiles the containment test for parallel axes in;
    /// most rays have none and take the plain slab test.
    #[inline(always)]
    fn hit<const PARALLEL_AXES: bool>(&self, ray: &SlabRay, t_max: f32) -> (u32, Vec4) {
        let b = &self.bounds;
        let slab = |axis: usize| {
            let entry = Vec4::from_array(b[ray.near_plane[axis]]);
            let exit = Vec4::from_array(b[ray.near_plane[axis] ^ 1]);
            if PARALLEL_AXES && ray.parallel[axis] {
                // The whole line or none of it: is the origin interval
                // [far_origin, near_origin] inside [min, max]?
                let inside = entry.cmple(ray.near_origin[axis]) & ray.far_origin[axis].cmple(exit);
                (
                    Vec4::select(inside, Vec4::NEG_INFINITY, Vec4::INFINITY),
                    Vec4::select(inside, Vec4::INFINITY, Vec4::NEG_INFINITY),
                )
            } else {
                (
                    (entry - ray.near_origin[axis]) * ray.inv[axis],
                    (exit - ray.far_origin[axis]) * ray.inv[axis],
                )
            }
        };
        let ((n0, f0), (n1, f1), (n2, f2)) = (slab(0), slab(1), slab(2));
        let near = n0.max(n1).max(n2).max(Vec4::ZERO) * NEAR_SCALE;
        let far = (f0.min(f1).min(f2) * FAR_SCALE).min(Vec4::splat(t_max));
        (near.cmple(far).bitmask(), near)
    }
}

/// The slots of `mask` (bit s set: child s is entered) in increasing order
/// of their entry distance `near` (≥ 0), in the low two bits of the first
/// `mask.count_ones()` entries. A sorting network over keys whose high
/// bits are the distance's (non-negative floats order like their bits) and
/// whose low two bits are the slot: no data-dependent branch, which on
/// random rays would be mispredicted about half the time.
#[inline(always)]
fn nearest_first(near: Vec4, mask: u32) -> [u32; 4] {
    let bits = near.to_array().map(|x| x.to_bits() & 0x7FFF_FFFC);
    let mut key: [u32; 4] = std::array::from_fn(|s| {
        if mask & (1 << s) != 0 {
            bits[s] | s as u32
        } else {
            u32::MAX
        }
    });
    for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        let (lo, hi) = (key[a].min(key[b]), key[a].max(key[b]));
        key[a] = lo;
        key[b] = hi;
    }
    key
}

/// The slots of `mask` in increasing slot order, laid out as
/// [`nearest_first`] lays them out.
#[inline(always)]
fn in_slot_order(mask: u32) -> [u32; 4] {
    let mut order = [u32::MAX; 4];
    let mut rest = mask;
    for entry in &mut order {
        if rest == 0 {
            break;
        }
        *entry = rest.trailing_zeros();
        rest &= rest - 1;
    }
    order
}

/// The f32 slab distances carry a relative rounding error of a few ulps
/// (f32 direction and inverse, one subtraction, one product: below 6·2⁻²⁴)
/// and keep their sign, so scaling by 1 ∓ 2⁻²⁰ makes them conservative
/// (pbrt-v4's robust slab test, with the origin handled below).
const NEAR_SCALE: f32 = 1.0 - 1.0 / 1_048_576.0;
const FAR_SCALE: f32 = 1.0 + 1.0 / 1_048_576.0;

/// A ray prepared for f32 slab tests that never miss a box the exact f64
/// ray enters: the origin is an f32 interval `[lo, hi]` containing the f64
/// origin, entry planes are measured from the end that gives the smaller
/// distance and exit planes from the other. No operation can produce a NaN:
/// inverses are finite, and axes the ray (nearly) runs along are tested by
/// containment instead.
struct SlabRay {
    /// Per axis: the row of [`Node::bounds`] holding the entry plane (min
    /// for a positive direction component, max otherwise); `^ 1` is the exit.
    near_plane: [usize; 3],
    near_origin: [Vec4; 3],
    far_origin: [Vec4; 3],
    inv: [Vec4; 3],
    /// Axes with |direction| < [`PARALLEL`].
    parallel: [bool; 3],
}

/// Direction components below this magnitude count as parallel to their
/// axis, so every inverse fits an f32 with room to spare. The drift such a
/// component allows over the ray's reach is added to the origin interval.
const PARALLEL: f64 = 1e-30;

impl SlabRay {
    /// `reach` bounds the distance along the ray that can matter (to any
    /// point of the tree, or `t_max` if smaller). Written without
    /// data-dependent branches: direction signs are random per ray.
    #[inline(always)]
    fn new(origin: DVec3, dir: DVec3, reach: f64) -> SlabRay {
        let mut ray = SlabRay {
            near_plane: [0; 3],
            near_origin: [Vec4::ZERO; 3],
            far_origin: [Vec4::ZERO; 3],
            inv: [Vec4::ZERO; 3],
            parallel: [false; 3],
        };
        for axis in 0..3 {
            let (o, d) = (origin[axis], dir[axis]);
            let parallel = d.abs() < PARALLEL;
            let drift = if parallel { d.abs() * reach } else { 0.0 };
            let (lo, hi) = ((o - drift) as f32, (o + drift) as f32);
            // Two ulps of margin (|x|·2⁻²² ≥ 2 ulp(x)) cover the half ulp of
            // the conversion and the rounding of the subtraction itself; the
            // absolute term covers subnormals near 0.
            let lo = lo - (lo.abs() * MARGIN + f32::MIN_POSITIVE);
            let hi = hi + (hi.abs() * MARGIN + f32::MIN_POSITIVE);
            // Entering through min (d > 0) the distance grows with the
            // origin, so the larger origin `hi` gives a lower bound; exits
            // take the other end. Mirrored for d < 0. Parallel axes use the
            // d > 0 layout for their containment test.
            let negative = d < 0.0 && !parallel;
            ray.near_plane[axis] = 2 * axis + negative as usize;
            ray.near_origin[axis] = Vec4::splat(if negative { lo } else { hi });
            ray.far_origin[axis] = Vec4::splat(if negative { hi } else { lo });
            ray.inv[axis] = Vec4::splat(if parallel { 0.0 } else { (1.0 / d) as f32 });
            ray.parallel[axis] = parallel;
        }
        ray
    }
}

/// Relative widening of the f32 origin interval (2⁻²²).
const MARGIN: f32 = 1.0 / 4_194_304.0;

/// Leaves larger than this are split even if the SAH prefers a leaf.
const MAX_LEAF: usize = 4;
/// Depth from which the binary tree stops asking the SAH and halves ranges
/// instead (so leaves stay ≤ [`MAX_LEAF`] whatever the geometry); ranges of
/// fewer than 2³² primitives are halved down to leaves within 32 more levels.
const MAX_DEPTH: usize = 60;
const TREE_DEPTH: usize = MAX_DEPTH + 32;
/// Each level of the 4-wide tree leaves at most three siblings waiting.
const STACK: usize = 3 * (TREE_DEPTH + 1) + 4;
// Leaf slots hold their count in 4 bits and their first primitive in 27.
const _: () = assert!(MAX_LEAF < 1 << (31 - LEAF_COUNT_SHIFT));
const _: () = assert!(super::MAX_TRIANGLES <= LEAF_FIRST_MASK as usize);
const _: () = assert!(super::MAX_SHAPES <= LEAF_FIRST_MASK as usize);

/// A 4-wide BVH: a binned-SAH binary tree collapsed so that every node
/// tests four child boxes at once (one f32 SIMD slab test).
pub struct Bvh {
    nodes: Vec<Node>,
    /// Largest coordinate magnitude of the tree's bounds.
    extent: f64,
}

/// Bytes of one BVH node.
pub const NODE_BYTES: usize = std::mem::size_of::<Node>();

impl Bvh {
    /// Bytes the tree holds on the heap.
    pub fn heap_bytes(&self) -> u64 {
        (self.nodes.capacity() * NODE_BYTES) as u64
    }

    /// Closest-hit traversal. `intersect(i, t_max)` tests primitive position
    /// `i` and returns its hit distance if it is below `t_max`; the caller
    /// records whatever else it needs. Returns the closest distance found.
    /// `prims` are the primitives in build order, read only to prefetch
    /// the leaves the ray will visit (an empty slice prefetches none).
    #[inline]
    pub fn closest<P>(
        &self,
        origin: DVec3,
        dir: DVec3,
        mut t_max: f64,
        prims: &[P],
        mut intersect: impl FnMut(usize, f64) -> Option<f64>,
    ) -> Option<f64> {
        let mut found = None;
        // The callbacks are inlined into the traversal loop: a call per
        // primitive spilled the ray's SIMD registers (+5 % on the Cornell
        // box inlined, the same on the mesh).
        self.traverse::<true, P>(
            origin,
            dir,
            &mut t_max,
            prims,
            #[inline(always)]
            |i, t_max| {
                if let Some(t) = intersect(i, *t_max) {
                    *t_max = t;
                    found = Some(t);
                }
                false
            },
        );
        found
    }

    /// Any-hit traversal: true as soon as `intersect(i, t_max)` reports a
    /// hit. `prims` as for [`Bvh::closest`].
    #[inline]
    pub fn any<P>(
        &self,
        origin: DVec3,
        dir: DVec3,
        mut t_max: f64,
        prims: &[P],
        mut intersect: impl FnMut(usize, f64) -> bool,
    ) -> bool {
        // Any hit ends the search, so the order of the children does not
        // matter: they wait on the stack in slot order, unsorted.
        self.traverse::<false, P>(
            origin,
            dir,
            &mut t_max,
            prims,
            #[inline(always)]
            |i, t_max| intersect(i, *t_max),
        )
    }

    /// Traversal, front to back if `NEAREST_FIRST`; `visit` may shrink
    /// `t_max` and returns true to stop.
    #[inline(always)]
    fn traverse<const NEAREST_FIRST: bool, P>(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_max: &mut f64,
        prims: &[P],
        mut visit: impl FnMut(usize, &mut f64) -> bool,
    ) -> bool {
        // A ray with a NaN or infinite coordinate hits nothing: its slab
        // tests would pass every child (NaN compares false both ways).
        if self.nodes.is_empty() || !(origin.is_finite() && dir.is_finite()) || t_max.is_nan() {
            return false;
        }
        // Every point of the tree lies within this distance of the origin.
        let reach = 2.0 * (origin.abs().max_element() + self.extent);
        let ray = SlabRay::new(origin, dir, reach.min(*t_max));
        let prefetch =
            self.nodes.len() * NODE_BYTES + std::mem::size_of_val(prims) > PREFETCH_ABOVE;
        let prims = if prefetch { prims } else { &[] };
        if ray.parallel.contains(&true) {
            self.walk::<true, NEAREST_FIRST, P>(&ray, t_max, prims, &mut visit)
        } else {
            self.walk::<false, NEAREST_FIRST, P>(&ray, t_max, prims, &mut visit)
        }
    }

    #[inline(always)]
    fn walk<const PARALLEL_AXES: bool, const NEAREST_FIRST: bool, P>(
        &self,
        ray: &SlabRay,
        t_max: &mut f64,
        prims: &[P],
        visit: &mut impl FnMut(usize, &mut f64) -> bool,
    ) -> bool {
        let mut t_max32 = round_up(*t_max);
        // Children wait with their entry distance, so a pop can drop them
        // without a second box test once a closer hit is known.
        let mut stack = [std::mem::MaybeUninit::<(u32, f32)>::uninit(); STACK];
        let mut top = 0usize;
        let mut current = (0u32, 0.0f32); // the root node, entered at 0
        loop {
            let (code, entry) = current;
            if entry <= t_max32 {
                if code & LEAF != 0 {
                    for i in leaf_range(code) {
                        if visit(i, t_max) {
                            return true;
                        }
                    }
                    t_max32 = round_up(*t_max);
                } else {
                    let node = &self.nodes[code as usize];
                    let (mask, near) = node.hit::<PARALLEL_AXES>(ray, t_max32);
                    if mask != 0 {
                        // Nearest first: the first is visited next, the
                        // others wait on the stack, farthest deepest.
                        let order = if NEAREST_FIRST {
                            nearest_first(near, mask)
                        } else {
                            in_slot_order(mask)
                        };
                        let near = near.to_array();
                        let slot = |k: usize| (order[k] & 3) as usize;
                        for k in (1..mask.count_ones() as usize).rev() {
                            // Finite rays visit at most three waiting
                            // children per level (STACK holds them); a ray
                            // whose slab arithmetic overflowed to NaN may
                            // pass every child, and ends here as a miss
                            // rather than past the stack.
                            if top == STACK {
                                return false;
                            }
                            let child = node.child[slot(k)];
                            self.prefetch(child, prims);
                            stack[top].write((child, near[slot(k)]));
                            top += 1;
                        }
                        current = (node.child[slot(0)], near[slot(0)]);
                        continue;
                    }
                }
            }
            if top == 0 {
                return false;
            }
            top -= 1;
            // SAFETY: every entry below the old `top` was written.
            current = unsafe { stack[top].assume_init() };
        }
    }
}

/// Trees and primitives of fewer bytes than this stay in the caches of one
/// core, where prefetching only costs instructions (measured: −3 % on the
/// Cornell box, +15 to +35 % on the 101k-triangle mesh).
const PREFETCH_ABOVE: usize = 1 << 20;

impl Bvh {
    /// Asks the cache for a child's node or leaf primitives while the
    /// traversal goes on: incoherent rays spend a third of their time
    /// waiting for these loads, and a child that waits on the stack is
    /// loaded by the time it is popped. Nothing is prefetched when `prims`
    /// is empty.
    #[inline(always)]
    fn prefetch<P>(&self, child: u32, prims: &[P]) {
        if prims.is_empty() {
            return;
        }
        // Raw addresses only: the bytes (padding included) are never read.
        let (start, len) = if child & LEAF != 0 {
            let Some(leaf) = prims.get(leaf_range(child)) else {
                return;
            };
            (leaf.as_ptr().cast::<u8>(), size_of_val(leaf))
        } else {
            let Some(node) = self.nodes.get(child as usize) else {
                return;
            };
            ((node as *const Node).cast::<u8>(), NODE_BYTES)
        };
        // Every 64-byte line the bytes touch, from the line holding the first.
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let misalignment = start as usize % 64;
            let first_line = start.wrapping_sub(misalignment);
            for offset in (0..misalignment + len).step_by(64) {
                // SAFETY: a prefetch never faults, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(first_line.wrapping_add(offset).cast()) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (start, len);
    }
}

#[cfg(test)]
mod tests;
