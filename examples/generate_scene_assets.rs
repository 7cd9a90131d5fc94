//! Regenerates the procedural assets of the bundled scenes:
//! `scenes/sky.exr` (sky with a sun lobe), `scenes/overcast.exr` (a smooth
//! overcast sky), `scenes/dusk.hdr` (a dusk sky, Radiance HDR),
//! `scenes/textures/tiles.png` (floor tiles, sRGB) and
//! `scenes/meshes/blob.obj` (a displaced sphere of 101 760 triangles).
//!
//! Usage: `cargo run --example generate_scene_assets [-- OUTPUT_DIR]`
//! (default `scenes`).

fn main() -> anyhow::Result<()> {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "scenes".into());
    bmc_irradiance::scene::generate::write_bundled_assets(std::path::Path::new(&dir))?;
    println!(
        "wrote {dir}/sky.exr, {dir}/overcast.exr, {dir}/dusk.hdr, {dir}/textures/tiles.png and {dir}/meshes/blob.obj"
    );
    Ok(())
}
