//! One file per resource. Every handler carries a `#[utoipa::path]` annotation
//! and is registered through `utoipa_axum::routes!`, so `/openapi.json` lists
//! exactly the routes the router serves.

pub mod cache;
pub mod health;
pub mod irradiance;
pub mod metrics;
pub mod openapi;
pub mod presets;
pub mod quadratures;
pub mod radiance;
pub mod records;
pub mod scenes;
pub mod tile_get;
pub mod tiles;
