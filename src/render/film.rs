//! The whole camera image, rendered tile by tile by an integrator and
//! assembled. Tiles are rendered one after
//! another (each in parallel over its pixels), so progress can be reported
//! per tile; by the reproducibility rule of `tile`, the image does not
//! depend on the tile size.

use super::error::RenderError;
use super::path::PathDepth;
use super::tile::{RenderedTile, TileRequest};
use super::transport::Transport;
use crate::image::Image;

/// Largest accepted tile side for [`Transport::render_image_by`].
pub const MAX_TILE_SIDE: u32 = 2048;

/// The work per pixel of a whole-image render (see [`TileRequest`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageSettings {
    pub samples_per_pixel: u32,
    pub max_depth: PathDepth,
    pub seed: u64,
}

impl ImageSettings {
    /// The request for the tile at (x, y) of size width × height.
    pub fn tile(&self, x: u32, y: u32, width: u32, height: u32) -> TileRequest {
        TileRequest {
            x,
            y,
            width,
            height,
            samples_per_pixel: self.samples_per_pixel,
            max_depth: self.max_depth,
            seed: self.seed,
            pass: 0,
            passes: 1,
        }
    }
}

/// A rendered camera image and the work it took.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderedImage {
    pub image: Image,
    /// Closest-hit plus shadow rays traced, camera rays included.
    pub rays: u64,
}

impl Transport {
    /// The camera's whole image as square tiles of side `tile_side`
    /// (smaller at the right and bottom edges), each rendered by `render`
    /// (an integrator's tile), in row-major tile order.
    pub fn render_image_by(
        &self,
        settings: &ImageSettings,
        tile_side: u32,
        render: &dyn Fn(&TileRequest) -> Result<RenderedTile, RenderError>,
    ) -> Result<RenderedImage, RenderError> {
        let (width, height) = self.scene().camera.resolution();
        if tile_side == 0 || tile_side > MAX_TILE_SIDE {
            return Err(RenderError::InvalidOption {
                field: "tile",
                reason: format!("{tile_side} is not in 1..={MAX_TILE_SIDE}"),
            });
        }
        let mut image = Image::black(width, height).map_err(|e| RenderError::InvalidOption {
            field: "width",
            reason: e.to_string(),
        })?;
        let mut rays = 0;
        for y in (0..height).step_by(tile_side as usize) {
            for x in (0..width).step_by(tile_side as usize) {
                let request =
                    settings.tile(x, y, tile_side.min(width - x), tile_side.min(height - y));
                let tile = render(&request)?;
                image
                    .insert(&tile.image, x, y)
                    .map_err(|e| RenderError::InvalidOption {
                        field: "tile",
                        reason: e.to_string(),
                    })?;
                rays += tile.rays;
            }
        }
        Ok(RenderedImage { image, rays })
    }
}
