//! Where a scene is sampled for fits and calibrations: points on its
//! surfaces by area, or what its camera sees. Deterministic in a seed.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use crate::render::QueryPoint;
use crate::render::Transport;

/// Up to `count` points on non-emitting surfaces, shape chosen by area, then
/// uniform on it; deterministic in `seed`.
pub fn training_points(transport: &Transport, count: usize, seed: u64) -> Vec<QueryPoint> {
    let scene = transport.scene();
    let shapes: Vec<usize> = (0..scene.shape_count())
        .filter(|&s| scene.shape_emitter(s).is_none() && scene.shape_area(s) > 0.0)
        .collect();
    let total: f64 = shapes.iter().map(|&s| scene.shape_area(s)).sum();
    if !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..count)
        .filter_map(|_| {
            let mut target = rng.random::<f64>() * total;
            let shape = *shapes
                .iter()
                .find(|&&s| {
                    target -= scene.shape_area(s);
                    target < 0.0
                })
                .unwrap_or(shapes.last()?);
            let (position, normal, _) =
                scene.sample_shape_area(shape, [rng.random(), rng.random()]);
            QueryPoint::new(position, normal).ok()
        })
        .collect()
}

/// Up to `count` camera-visible surface points (module docs), deterministic in `seed`.
pub fn camera_points(transport: &Transport, count: usize, seed: u64) -> Vec<QueryPoint> {
    let scene = transport.scene();
    let (width, height) = scene.camera.resolution();
    let mut rng = Pcg64::seed_from_u64(seed);
    // A grid with about twice as many cells as points, visited in random
    // order, so misses and back faces still leave enough points.
    let cells = (2 * count).max(1);
    let columns = ((cells as f64 * width as f64 / height as f64).sqrt().ceil() as usize).max(1);
    let rows = cells.div_ceil(columns).max(1);
    let mut order: Vec<usize> = (0..columns * rows).collect();
    for i in (1..order.len()).rev() {
        order.swap(i, rng.random_range(0..=i));
    }
    let mut points = Vec::with_capacity(count);
    for cell in order {
        if points.len() == count {
            break;
        }
        let (cx, cy) = (cell % columns, cell / columns);
        let px = (cx as f64 + rng.random::<f64>()) / columns as f64 * width as f64;
        let py = (cy as f64 + rng.random::<f64>()) / rows as f64 * height as f64;
        let ray = scene.camera.generate_ray(px, py);
        let Some(hit) = scene.intersect(&ray) else {
            continue;
        };
        if hit.emitter.is_some() || hit.normal.dot(ray.dir) >= 0.0 {
            continue;
        }
        if let Ok(point) = QueryPoint::new(hit.position, hit.shading_normal) {
            points.push(point);
        }
    }
    points
}
