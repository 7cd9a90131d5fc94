//! The integration tests, in one binary so that CI links once instead of
//! once per file. Each module is one area; `common` starts a real server on
//! an ephemeral port. `tests/service_quadratures_concurrent.rs` stays a
//! binary of its own, as it reads the process-wide metrics recorder.

mod common;

mod calibration;
mod cli_quadrature;
mod cluster;
mod concurrent_first_requests;
mod docs_references;
mod first_run;
mod fuzz_requests;
mod hostile_scenes;
mod irradiance_cache;
mod irradiance_cli;
mod layering;
mod light_transport;
mod loadtest;
mod mitsuba_images;
mod mitsuba_irradiance;
mod mitsuba_xml;
mod plugin_layout;
mod readme_commands;
mod regression;
mod scene_parameters;
mod service_archive;
mod service_bad_inputs;
mod service_bad_scenes;
mod service_basics;
mod service_estimators;
mod service_irradiance;
mod service_persistence;
mod service_quadratures;
mod service_radiance;
mod service_robustness;
mod service_scenes;
mod service_tile_get;
mod service_tiles;
mod service_upload;
mod viewer_browser;
mod walkthrough;
