//! Construction of the [`Bvh`]: a binary tree by the binned surface area
//! heuristic, its splits decided first (the halves of large ranges on two
//! threads) and its nodes numbered by one depth-first walk, so the tree is
//! the same whatever the thread count; then collapsed to four children per
//! node.

use glam::DVec3;

use super::{Aabb, Bvh, LEAF, LEAF_COUNT_SHIFT, MAX_DEPTH, MAX_LEAF, Node};

/// SAH cost of one traversal step relative to one primitive test.
const TRAVERSAL_COST: f64 = 1.0;
const BINS: usize = 16;

/// Node of the binary SAH tree the builder makes before collapsing it:
/// interior nodes have `count == 0` and children `first`, `first + 1`;
/// leaves hold primitives `first .. first + count` in build order.
#[derive(Clone, Copy, Debug)]
struct BinaryNode {
    bounds: Aabb,
    first: u32,
    count: u32,
}

impl Bvh {
    /// Builds a tree over `bounds`. Returns the tree and the build order:
    /// leaf ranges index positions in `order`, and `order[i]` is the index in
    /// `bounds` of the primitive at position `i`. Callers store their
    /// primitives permuted by `order`.
    ///
    /// Fewer than 2N/3 nodes for N primitives: a node with fewer than four
    /// children holds only leaves (it would have opened an interior child
    /// otherwise), so with n₄ full nodes, n' others and L ≤ N leaves,
    /// counting child slots gives 3n₄ + n' ≤ L − 1 and 2n' ≤ L.
    pub fn build(bounds: &[Aabb]) -> (Bvh, Vec<u32>) {
        let (binary, order) = build_binary(bounds);
        let extent = binary.first().map_or(0.0, |root| {
            root.bounds
                .min
                .abs()
                .max(root.bounds.max.abs())
                .max_element()
        });
        let nodes = collapse(&binary);
        (Bvh { nodes, extent }, order)
    }
}

/// Ranges of at least this many primitives split their two halves on two
/// threads; below it a thread is not worth its hand-off.
pub(super) const PARALLEL_RANGE: usize = 16 * 1024;

/// How a range of primitives was split, decided before nodes are numbered.
enum Decision {
    Leaf {
        bounds: Aabb,
    },
    Split {
        bounds: Aabb,
        mid: usize,
        children: Box<[Decision; 2]>,
    },
}

/// Decides the splits of `range` (reordered in place) at `depth`, the two
/// halves of large ranges on two threads: the decisions and the final order
/// depend only on the input, never on the threads.
fn decide(range: &mut [u32], bounds: &[Aabb], centroids: &[DVec3], depth: usize) -> Decision {
    let bb = range
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.union(bounds[i as usize]));
    // Where the SAH cannot split (past the depth bound, or all centroids
    // coincide) a range too big for a leaf is halved.
    let sah = (depth < MAX_DEPTH)
        .then(|| split(range, bounds, centroids, &bb))
        .flatten();
    let Some(mid) = sah.or_else(|| (range.len() > MAX_LEAF).then_some(range.len() / 2)) else {
        return Decision::Leaf { bounds: bb };
    };
    let parallel = range.len() >= PARALLEL_RANGE;
    let (left, right) = range.split_at_mut(mid);
    let (l, r) = if parallel {
        rayon::join(
            || decide(left, bounds, centroids, depth + 1),
            || decide(right, bounds, centroids, depth + 1),
        )
    } else {
        (
            decide(left, bounds, centroids, depth + 1),
            decide(right, bounds, centroids, depth + 1),
        )
    };
    Decision::Split {
        bounds: bb,
        mid,
        children: Box::new([l, r]),
    }
}

/// The binned-SAH binary tree over `bounds` and the build order. Splits are
/// decided first ([`decide`], in parallel), then nodes are numbered by one
/// depth-first walk, so the tree is the same whatever the thread count.
fn build_binary(bounds: &[Aabb]) -> (Vec<BinaryNode>, Vec<u32>) {
    let mut order: Vec<u32> = (0..bounds.len() as u32).collect();
    if bounds.is_empty() {
        return (Vec::new(), order);
    }
    let centroids: Vec<DVec3> = bounds.iter().map(Aabb::centroid).collect();
    let root = decide(&mut order, bounds, &centroids, 0);
    let empty = BinaryNode {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
    };
    let mut nodes = vec![empty];
    nodes.reserve(2 * bounds.len());
    let mut todo = vec![(0usize, 0usize, bounds.len(), &root)];
    while let Some((index, start, end, decision)) = todo.pop() {
        nodes[index] = match decision {
            Decision::Split {
                bounds,
                mid,
                children,
            } => {
                let left = nodes.len();
                nodes.extend([empty, empty]);
                todo.push((left, start, start + mid, &children[0]));
                todo.push((left + 1, start + mid, end, &children[1]));
                BinaryNode {
                    bounds: *bounds,
                    first: left as u32,
                    count: 0,
                }
            }
            Decision::Leaf { bounds } => BinaryNode {
                bounds: *bounds,
                first: start as u32,
                count: (end - start) as u32,
            },
        };
    }
    (nodes, order)
}

/// Collapses a binary tree into 4-wide nodes: each node starts from a
/// binary node's two children and keeps opening the interior child of
/// largest surface area until it has four (Wald et al., "Getting Rid of
/// Packets", 2008, build their 4-wide trees the same way).
fn collapse(binary: &[BinaryNode]) -> Vec<Node> {
    if binary.is_empty() {
        return Vec::new();
    }
    let children = |b: &BinaryNode| [b.first as usize, b.first as usize + 1];
    let mut nodes = vec![Node::EMPTY];
    let mut todo = vec![(0usize, 0usize)]; // binary node, wide node
    while let Some((b, wide)) = todo.pop() {
        let mut slots: Vec<usize> = if binary[b].count > 0 {
            vec![b] // a leaf root
        } else {
            children(&binary[b]).to_vec()
        };
        while slots.len() < 4 {
            let open = slots
                .iter()
                .enumerate()
                .filter(|(_, k)| binary[**k].count == 0)
                .max_by(|(_, a), (_, b)| {
                    binary[**a]
                        .bounds
                        .half_area()
                        .total_cmp(&binary[**b].bounds.half_area())
                })
                .map(|(j, _)| j);
            let Some(j) = open else { break };
            let k = slots.swap_remove(j);
            slots.extend(children(&binary[k]));
        }
        let mut node = Node::EMPTY;
        for (slot, &k) in slots.iter().enumerate() {
            let child = &binary[k];
            node.set_bounds(slot, &child.bounds);
            node.child[slot] = if child.count > 0 {
                LEAF | (child.count << LEAF_COUNT_SHIFT) | child.first
            } else {
                nodes.push(Node::EMPTY);
                todo.push((k, nodes.len() - 1));
                (nodes.len() - 1) as u32
            };
        }
        nodes[wide] = node;
    }
    nodes
}

/// Binned SAH split of `range` (reordered in place): the number of
/// primitives going left, or `None` when the SAH prefers a leaf or all
/// centroids coincide (the caller halves ranges too big for a leaf).
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
        _ => None,
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
