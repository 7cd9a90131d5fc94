//! The path tracer: unidirectional path tracing with next-event
//! estimation, MIS and Russian roulette (the kernels of
//! [`crate::render::PathTracer::incident_radiance`]), emitters seen directly
//! included: the unbiased reference every other integrator is measured
//! against. It shades camera rays through the shared pixel loop
//! ([`render_tile_with`]), spreading each pixel's first light and BSDF
//! samples over the pixel's rays.

use rand_pcg::Pcg64;

use crate::render::{
    CameraRayShader, Cancel, Evaluation, ImageSettings, PathDepth, PathLengths, PathLimits,
    PixelSample, RenderError, RenderedImage, RenderedTile, SamplePlan, SharedFirstVertex,
    TileRequest, TraceStats, Transport, render_tile_with,
};
use crate::scene::{Ray, Scene};

/// The path tracer on one scene.
#[derive(Clone, Copy)]
pub struct PathIntegrator<'a> {
    transport: &'a Transport,
}

impl<'a> PathIntegrator<'a> {
    pub fn new(transport: &'a Transport) -> Self {
        Self { transport }
    }

    pub fn transport(&self) -> &'a Transport {
        self.transport
    }

    /// Radiance arriving along `ray` (W/(m²·sr)) by one path of up to
    /// `max_depth` segments, `ray` being its first.
    pub fn radiance(
        &self,
        ray: Ray,
        max_depth: PathDepth,
        rng: &mut Pcg64,
        stats: &mut TraceStats,
    ) -> Evaluation {
        let limits = PathLimits {
            max_depth,
            lengths: PathLengths::All,
        };
        Evaluation::of(
            self.transport
                .paths()
                .incident_radiance(ray, limits, rng, stats)
                .radiance,
        )
    }

    /// Renders one tile of the scene camera's image, in parallel over its
    /// pixels on the current rayon pool; stops between pixels once `cancel` is set.
    /// `plan`: the rays per pixel of an adaptive pass ([`render_tile_with`]).
    pub fn render_tile(
        &self,
        request: &TileRequest,
        plan: Option<&SamplePlan>,
        cancel: &Cancel,
    ) -> Result<RenderedTile, RenderError> {
        let shader = PathTracer {
            transport: self.transport,
            max_depth: request.max_depth,
        };
        render_tile_with(
            &self.transport.scene().camera,
            &shader,
            request,
            plan,
            cancel,
        )
    }

    /// Renders the camera's whole image as square tiles of side `tile_side`;
    /// `on_tile` is called after each tile (e.g. to advance a progress bar).
    /// By the pixel loop's reproducibility rule the image does not depend
    /// on the tile size.
    pub fn render_image(
        &self,
        settings: &ImageSettings,
        tile_side: u32,
        on_tile: &dyn Fn(&RenderedTile),
    ) -> Result<RenderedImage, RenderError> {
        self.transport
            .render_image_by(settings, tile_side, &|request| {
                let tile = self.render_tile(request, None, &Cancel::never())?;
                on_tile(&tile);
                Ok(tile)
            })
    }
}

/// The path tracer as a camera-ray shader: paths of up to `max_depth`
/// segments counted from the camera.
struct PathTracer<'a> {
    transport: &'a Transport,
    max_depth: PathDepth,
}

impl CameraRayShader for PathTracer<'_> {
    fn scene(&self) -> &Scene {
        self.transport.scene()
    }

    fn radiance(
        &self,
        ray: Ray,
        sample: PixelSample,
        rng: &mut Pcg64,
        stats: &mut TraceStats,
    ) -> Evaluation {
        // The camera ray is the path's first segment, so emitters it hits
        // count at full weight (path.rs) — they are seen directly. The
        // pixel's rays spread their first light and BSDF samples over
        // shared patterns, as their positions over the pixel.
        let limits = PathLimits {
            max_depth: self.max_depth,
            lengths: PathLengths::All,
        };
        let first = SharedFirstVertex::new(sample.index, sample.count, sample.pattern);
        Evaluation::of(
            self.transport
                .paths()
                .incident_radiance_stratified(ray, limits, first, rng, stats)
                .radiance,
        )
    }
}

#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::path::Path;
    use std::sync::Arc;

    use super::*;
    use crate::image::Image;
    use crate::render::tile::tests::{assert_tiling_keeps_the_image, request};
    use crate::render::{MAX_SAMPLES_PER_PIXEL, RenderError};
    use crate::scene::Scene;
    use crate::testing::{cornell, in_pool};

    #[test]
    fn tiles_and_thread_counts_give_bit_identical_pixels() {
        let transport = cornell(32);
        let whole = in_pool(1, || {
            PathIntegrator::new(&transport).render_tile(
                &request(0, 0, 32, 32),
                None,
                &Cancel::never(),
            )
        })
        .expect("renders");
        let mut assembled = Image::black(32, 32).expect("valid");
        let mut rays = 0;
        for (x, y) in [(0, 0), (16, 0), (0, 16), (16, 16)] {
            let tile = in_pool(2, || {
                PathIntegrator::new(&transport).render_tile(
                    &request(x, y, 16, 16),
                    None,
                    &Cancel::never(),
                )
            })
            .expect("renders");
            assert_eq!((tile.x, tile.y), (x, y));
            assembled.insert(&tile.image, x, y).expect("fits");
            rays += tile.rays;
        }
        assert_tiling_keeps_the_image(&assembled, &whole.image, 16);
        assert_eq!(rays, whole.rays);
        let again = in_pool(2, || {
            PathIntegrator::new(&transport).render_tile(
                &request(0, 0, 32, 32),
                None,
                &Cancel::never(),
            )
        })
        .expect("renders");
        assert_eq!(again, whole);
        // The image is not trivially uniform: the seed matters and light arrives.
        let other_seed = TileRequest {
            seed: 8,
            ..request(0, 0, 32, 32)
        };
        assert_ne!(
            PathIntegrator::new(&transport)
                .render_tile(&other_seed, None, &Cancel::never())
                .expect("renders")
                .image,
            whole.image
        );
        assert!(whole.image.rgb().iter().any(|p| p[0] > 0.0));
        assert!(whole.rays >= 32 * 32 * 2);
    }

    #[test]
    fn bad_requests_name_the_field() {
        let transport = cornell(32);
        let field = |r: TileRequest| match PathIntegrator::new(&transport).render_tile(
            &r,
            None,
            &Cancel::never(),
        ) {
            Err(RenderError::InvalidOption { field, .. }) => field,
            other => panic!("{r:?} gave {other:?}"),
        };
        assert_eq!(field(request(32, 0, 1, 1)), "x");
        assert_eq!(field(request(0, 40, 1, 1)), "y");
        assert_eq!(field(request(20, 0, 13, 1)), "width");
        assert_eq!(field(request(0, 31, 1, 2)), "height");
        assert_eq!(field(request(0, 0, 0, 4)), "width");
        assert_eq!(field(request(0, 0, 4, 0)), "height");
        assert_eq!(field(request(1, 0, u32::MAX, 1)), "width");
        let spp = |samples_per_pixel| TileRequest {
            samples_per_pixel,
            ..request(0, 0, 1, 1)
        };
        assert_eq!(field(spp(0)), "samples_per_pixel");
        assert_eq!(field(spp(MAX_SAMPLES_PER_PIXEL + 1)), "samples_per_pixel");
        let pass = |pass, passes| TileRequest {
            pass,
            passes,
            ..request(0, 0, 1, 1)
        };
        assert_eq!(field(pass(1, 1)), "pass");
        assert_eq!(field(pass(0, 0)), "pass");
        assert_eq!(field(pass(0, MAX_SAMPLES_PER_PIXEL)), "samples_per_pixel");
        // Inside a huge image but too large for one request.
        let huge = TileRequest {
            width: 4096,
            height: 4096,
            ..request(0, 0, 1, 1)
        };
        assert!(matches!(
            huge.validate((16384, 16384)),
            Err(RenderError::InvalidOption { field: "width", .. })
        ));
        assert!(request(0, 0, 2048, 2048).validate((4096, 4096)).is_ok());
    }

    #[test]
    fn an_emitter_filling_the_view_renders_its_radiance_exactly() {
        // A 20 × 20 emitting rectangle at z = 0 facing the camera at z = 5;
        // the view spans ±1.9 there, and nothing else exists to reflect.
        let text = r#"{
            "materials": [{"id": "m", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
            "shapes": [{"type": "rectangle", "material": "m",
                        "to_world": {"scale": [10, 10, 1]},
                        "emitter": {"type": "area", "radiance": [3.5, 0.25, 7.0]}}],
            "camera": {"fov": 40, "width": 6, "height": 4,
                       "origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}
        }"#;
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::from_json_str(text, root, root).expect("loads");
        let transport = Transport::new(Arc::new(scene));
        let tile = PathIntegrator::new(&transport)
            .render_tile(
                &TileRequest {
                    samples_per_pixel: 8,
                    ..request(0, 0, 6, 4)
                },
                None,
                &Cancel::never(),
            )
            .expect("renders");
        for (p, v) in tile
            .image
            .rgb()
            .iter()
            .zip(tile.image.variance().expect("set"))
        {
            assert_eq!(*p, [3.5, 0.25, 7.0]);
            assert_eq!(*v, 0.0);
        }
    }

    #[test]
    fn any_tile_size_gives_the_same_image() {
        let transport = cornell(12);
        let whole = PathIntegrator::new(&transport)
            .render_tile(&request(0, 0, 12, 12), None, &Cancel::never())
            .expect("renders");
        let r = request(0, 0, 1, 1);
        let settings = ImageSettings {
            samples_per_pixel: r.samples_per_pixel,
            max_depth: r.max_depth,
            seed: r.seed,
        };
        let tiles = Cell::new(0);
        let rendered = PathIntegrator::new(&transport)
            .render_image(&settings, 5, &|_| tiles.set(tiles.get() + 1))
            .expect("renders");
        assert_eq!(tiles.get(), 9);
        assert_tiling_keeps_the_image(&rendered.image, &whole.image, 5);
        assert_eq!(rendered.rays, whole.rays);
        assert!(matches!(
            PathIntegrator::new(&transport).render_image(&settings, 0, &|_| {}),
            Err(RenderError::InvalidOption { field: "tile", .. })
        ));
    }
}
