use super::build::PARALLEL_RANGE;
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
    // The larger set is above `PREFETCH_ABOVE`, so its traversal
    // prefetches nodes and leaves.
    for n in [500, 30_000] {
        traversal_agrees_with_brute_force_on(&random_boxes(n, 7));
    }
}

fn traversal_agrees_with_brute_force_on(boxes: &[Aabb]) {
    let (bvh, order) = Bvh::build(boxes);
    assert!(3 * bvh.nodes.len() < 2 * boxes.len());
    let prims: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
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
        let got = bvh.closest(o, d, t_max, &prims, |i, t_max| {
            box_hit(&prims[i], o, d, t_max).filter(|&t| t < t_max)
        });
        assert_eq!(got, expected);
        let any = bvh.any(o, d, t_max, &prims, |i, t_max| {
            box_hit(&prims[i], o, d, t_max).is_some()
        });
        assert_eq!(any, expected.is_some());
    }
}

#[test]
fn slot_order_lists_the_slots_of_the_mask() {
    for mask in 1u32..16 {
        let order = in_slot_order(mask);
        let count = mask.count_ones() as usize;
        let expected: Vec<u32> = (0..4).filter(|s| mask & (1 << s) != 0).collect();
        assert_eq!(order[..count], expected[..], "mask {mask:b}");
    }
}

#[test]
fn children_are_ordered_nearest_first() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    for _ in 0..2000 {
        let mask: u32 = rng.random_range(1..16);
        // Whole numbers repeat often, so ties are exercised too.
        let near: [f32; 4] = std::array::from_fn(|_| rng.random_range(0..4) as f32);
        let order = nearest_first(Vec4::from_array(near), mask);
        let slots: Vec<usize> = order[..mask.count_ones() as usize]
            .iter()
            .map(|&k| (k & 3) as usize)
            .collect();
        let mut expected: Vec<usize> = (0..4).filter(|s| mask & (1 << s) != 0).collect();
        expected.sort_by(|&a, &b| near[a].total_cmp(&near[b]).then(a.cmp(&b)));
        assert_eq!(slots, expected, "near {near:?} mask {mask:b}");
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
    let hits = |o: DVec3, d: DVec3| bvh.any(o, d, 1e9, &[(); 0], |_, _| true);
    assert!(hits(DVec3::new(0.0, 5.0, 0.5), -DVec3::Y));
    assert!(hits(DVec3::new(-0.0, 5.0, 0.5), DVec3::new(0.0, -1.0, 0.0)));
    assert!(hits(DVec3::new(1.0, 5.0, 1.0), -DVec3::Y));
    assert!(hits(DVec3::new(1.0, 0.5, -2.0), DVec3::Z));
    assert!(!hits(DVec3::new(1.5, 0.5, -2.0), DVec3::Z));
}

#[test]
fn rays_along_a_face_agree_with_brute_force() {
    // Origins exactly on a box's face and directions (nearly) parallel
    // to it: the cases where an f32 slab test could round a hit away.
    let mut boxes = random_boxes(200, 3);
    boxes.push(Aabb {
        min: DVec3::ZERO,
        max: DVec3::ONE,
    });
    let (bvh, order) = Bvh::build(&boxes);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
    for k in 0..2000 {
        let b = &boxes[k % boxes.len()];
        let axis = k % 3;
        let mut o = b.min + (b.max - b.min) * DVec3::new(rng.random(), rng.random(), rng.random());
        o[axis] = if k % 2 == 0 { b.min[axis] } else { b.max[axis] };
        let mut d = (DVec3::new(rng.random(), rng.random(), rng.random()) - 0.5).normalize();
        d[axis] = [1e-300, -1e-300, 1e-40, -3e-30, 1e-20][k % 5];
        let expected = boxes
            .iter()
            .filter_map(|b| box_hit(b, o, d, 1e9))
            .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))));
        let got = bvh.closest(o, d, 1e9, &[(); 0], |i, t_max| {
            box_hit(&boxes[order[i] as usize], o, d, t_max).filter(|&t| t < t_max)
        });
        assert_eq!(got, expected, "ray {k}");
    }
}

#[test]
fn deep_unbalanced_trees_keep_small_leaves() {
    // Boxes halving in size towards the origin: the SAH peels off a few
    // at a time, so the SAH depth bound is reached with hundreds left.
    let boxes: Vec<Aabb> = (0..600)
        .map(|k| {
            let c = 0.5f64.powi(k);
            Aabb {
                min: DVec3::new(c, -c, -c),
                max: DVec3::new(2.0 * c, c, c),
            }
        })
        .collect();
    let (bvh, order) = Bvh::build(&boxes);
    let leaf_sizes = bvh
        .nodes
        .iter()
        .flat_map(|n| n.child)
        .filter(|c| c & LEAF != 0);
    assert!(
        leaf_sizes
            .map(|c| ((c & !LEAF) >> LEAF_COUNT_SHIFT) as usize)
            .all(|n| n <= MAX_LEAF)
    );
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    for _ in 0..500 {
        let o = DVec3::new(-1.0, 0.0, 0.0) + DVec3::new(0.0, rng.random(), rng.random()) * 1e-3;
        let d = (DVec3::new(1.0, 0.0, 0.0)
            + (DVec3::new(0.0, rng.random(), rng.random()) - 0.5) * 1e-3)
            .normalize();
        let expected = boxes
            .iter()
            .filter_map(|b| box_hit(b, o, d, 1e9))
            .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))));
        let mut seen = 0;
        let got = bvh.closest(o, d, 1e9, &[(); 0], |i, t_max| {
            seen += 1;
            box_hit(&boxes[order[i] as usize], o, d, t_max).filter(|&t| t < t_max)
        });
        assert_eq!(got, expected);
        assert!(seen > 0);
    }
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
    let mut leaf_sizes = bvh
        .nodes
        .iter()
        .flat_map(|n| n.child)
        .filter(|c| c & LEAF != 0);
    assert!(leaf_sizes.clone().count() >= 100 / MAX_LEAF);
    assert!(leaf_sizes.all(|c| ((c & !LEAF) >> LEAF_COUNT_SHIFT) as usize <= MAX_LEAF));
    let mut seen = 0;
    bvh.closest(
        DVec3::splat(-1.0),
        DVec3::ONE.normalize(),
        1e9,
        &[(); 0],
        |_, _| {
            seen += 1;
            None
        },
    );
    assert_eq!(seen, 100);
}

#[test]
fn the_tree_is_the_same_on_one_thread_or_several() {
    // Large enough that the top splits run on two threads.
    let boxes = random_boxes(4 * PARALLEL_RANGE, 7);
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let (bvh, order) = pool.install(|| Bvh::build(&boxes));
        let nodes: Vec<String> = bvh.nodes.iter().map(|n| format!("{n:?}")).collect();
        (nodes, order)
    };
    let (one, three) = (on(1), on(3));
    assert_eq!(one.1, three.1);
    assert!(one.0 == three.0, "the nodes differ");
    assert!(one.0.len() > boxes.len() / 4);
}

#[test]
fn rays_with_nan_or_huge_coordinates_miss_instead_of_overrunning_the_stack() {
    // Deep enough that a ray passing every child would need more than the
    // traversal stack holds.
    let boxes = random_boxes(30_000, 11);
    let (bvh, order) = Bvh::build(&boxes);
    let prims: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
    let nan = DVec3::splat(f64::NAN);
    let huge = DVec3::splat(1e300);
    for (origin, dir) in [
        (DVec3::splat(5.0), nan),
        (nan, DVec3::X),
        (DVec3::splat(f64::INFINITY), DVec3::X),
        // Finite, but the slab distances overflow to ±∞ and their
        // differences to NaN.
        (-huge, DVec3::new(1.0, 1e-300, 0.0)),
        (huge, -DVec3::ONE.normalize()),
    ] {
        let mut visited = 0;
        let hit = bvh.closest(origin, dir, f64::INFINITY, &prims, |_, _| {
            visited += 1;
            None
        });
        assert_eq!(hit, None);
        assert!(!bvh.any(origin, dir, f64::INFINITY, &prims, |_, _| false));
        assert!(visited <= prims.len());
    }
}
