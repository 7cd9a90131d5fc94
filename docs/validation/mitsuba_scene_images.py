#!/usr/bin/env python3
"""Mitsuba 3's renders of the small scenes in `tests/data/mitsuba/`, the
references of the Rust tests in `tests/it/mitsuba_images.rs`, each exercising
a few plugins: `lights.xml` (point, spot and directional lights; rough gold,
rough plastic, a two-sided disk), `textures.xml` (bitmaps and checkerboards
on every shape kind), `materials.xml` (blendbsdf, mask, thindielectric,
roughdielectric, plastic), `rough_maps.xml` (checkerboard and bitmap
roughness on conductors and a dielectric), `anisotropy.xml` (anisotropic
lobes along each shape's u direction), `textured_lights.xml` (area lights
with checkerboard and bitmap radiance), `spectra.xml` (spectra on emitters,
reflectances and a conductor's `eta`/`k`, and a `.spd` file), `cylinders.xml`
(textured, open and emitting cylinders), `orthographic.xml` (an
orthographic sensor), `point_cloud_0_6.xml` (a Mitsuba 0.6 file, written
by `--assets`), `envmap.xml` (a rotated, scaled HDR map),
`hide_emitters.xml`, `thinlens.xml`, `shading_normals.xml` (bump and normal
maps on rectangles, spheres, a mirrored OBJ quad and a two-sided disk),
`principled.xml` (the principled BSDF's lobes, textured, and transmission),
`principled_thin.xml` (thin principled sheets passing light); and `studio`, the bundled
`scenes/studio.xml` (every kind of material and light at once), at 80x60 to
`tests/data/mitsuba/studio_mitsuba.exr`.

Every reference is rendered with the file's own reconstruction filter (ours
reads box, gaussian and tent as Mitsuba does), at the file's own
resolution, to `<scene>_mitsuba.exr` beside it. First `--assets` writes
the images the scenes read:
- `uv_grid.png` (8-bit sRGB) and `uv_grid.exr` (linear): 4x4 texels whose
  colours name their column (red), row (green) and parity (blue), so any
  flip or shift of texture coordinates changes the picture;
- `sky.hdr`: a 32x16 sky, coarse enough that the lookup's interpolation
  shows, with a warm patch for a low sun;
- `bumps.png`: a 32x32 height field; `normals.png`: a 16x16 tangent-space
  normal map (both 8-bit, read `raw`).

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_scene_images.py --assets --spp 16384 \
        lights textures materials rough_maps anisotropy textured_lights spectra cylinders orthographic point_cloud_0_6 envmap hide_emitters thinlens shading_normals principled principled_thin studio
"""

import argparse
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

DIR = "tests/data/mitsuba"


def uv_grid():
    """The 4x4 texels, row 0 at the top, values in [0, 1]."""
    texels = np.zeros((4, 4, 3))
    for y in range(4):
        for x in range(4):
            texels[y, x] = [(x + 0.5) / 4, (y + 0.5) / 4, 0.15 + 0.7 * ((x + y) % 2)]
    return texels


def sky(width=32, height=16):
    """Rows from the +Y pole (top) to the -Y pole."""
    texels = np.zeros((height, width, 3), dtype=np.float32)
    for y in range(height):
        for x in range(width):
            up = 1.0 - (y + 0.5) / height * 2.0
            if up > 0:
                texels[y, x] = [0.3 + 0.4 * up, 0.5 + 0.3 * up, 0.9 + 0.2 * x / width]
            else:
                texels[y, x] = [0.15, 0.12, 0.1]
    texels[4:7, 9:12] = [8.0, 6.5, 4.0]
    return texels


# The Mitsuba 0.6 scene that published point-cloud figures are rendered with
# (the widely copied template of the point-cloud renderers on GitHub: camelCase
# properties, `ldsampler`, `farClip`/`nearClip`, a film `banner`, a glossy
# ground and a tilted area light), filled with 200 points of our own on a
# sphere, coloured by position as the template colours them.
POINT_CLOUD_HEAD = """<scene version="0.6.0">
    <default name="spp" value="256"/>
    <integrator type="path">
        <integer name="maxDepth" value="-1"/>
    </integrator>
    <sensor type="perspective">
        <float name="farClip" value="100"/>
        <float name="nearClip" value="0.1"/>
        <transform name="toWorld">
            <lookat origin="3,3,3" target="0,0,0" up="0,0,1"/>
        </transform>
        <float name="fov" value="25"/>
        <sampler type="ldsampler">
            <integer name="sampleCount" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="64"/>
            <integer name="height" value="48"/>
            <rfilter type="gaussian"/>
            <boolean name="banner" value="false"/>
        </film>
    </sensor>
    <bsdf type="roughplastic" id="surfaceMaterial">
        <string name="distribution" value="ggx"/>
        <float name="alpha" value="0.05"/>
        <float name="intIOR" value="1.46"/>
        <rgb name="diffuseReflectance" value="1,1,1"/>
    </bsdf>
"""
POINT_CLOUD_BALL = """
    <shape type="sphere">
        <float name="radius" value="0.025"/>
        <transform name="toWorld">
            <translate x="{:.6f}" y="{:.6f}" z="{:.6f}"/>
        </transform>
        <bsdf type="diffuse">
            <rgb name="reflectance" value="{:.6f},{:.6f},{:.6f}"/>
        </bsdf>
    </shape>
"""
POINT_CLOUD_TAIL = """
    <shape type="rectangle">
        <ref name="bsdf" id="surfaceMaterial"/>
        <transform name="toWorld">
            <scale x="10" y="10" z="1"/>
            <translate x="0" y="0" z="-0.5"/>
        </transform>
    </shape>
    <shape type="rectangle">
        <transform name="toWorld">
            <scale x="10" y="10" z="1"/>
            <lookat origin="-4,4,20" target="0,0,0" up="0,0,1"/>
        </transform>
        <emitter type="area">
            <rgb name="radiance" value="6,6,6"/>
        </emitter>
    </shape>
</scene>
"""


def point_cloud():
    points = np.random.default_rng(1).normal(size=(200, 3))
    points *= 0.4 / np.linalg.norm(points, axis=1)[:, None]
    balls = "".join(POINT_CLOUD_BALL.format(*p, *np.clip(p + 0.5, 0.001, 1)) for p in points)
    return POINT_CLOUD_HEAD + balls + POINT_CLOUD_TAIL


def bumps(size=32):
    """A height field in [0, 1]: round bumps on a gentle ramp in u, so that
    a flip of either texture direction or of the gradient's sign shows."""
    y, x = np.mgrid[0:size, 0:size] + 0.5
    h = 0.3 * x / size
    for cx, cy, r in [(8, 8, 5), (22, 10, 7), (12, 23, 6), (26, 26, 4)]:
        h += 0.6 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (r * r))
    return np.clip(h, 0, 1)


def normals(size=16):
    """A tangent-space normal map: normals tilted along x by the column and
    along y by the row (by up to 0.6), encoded (n + 1)/2."""
    y, x = np.mgrid[0:size, 0:size] + 0.5
    n = np.stack([0.6 * np.sin(2 * np.pi * x / size), 0.6 * (2 * y / size - 1), np.ones_like(x)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return (n + 1) / 2


def write_assets():
    open(f"{DIR}/point_cloud_0_6.xml", "w").write(point_cloud())
    mi.Bitmap(np.round(bumps() * 255).astype(np.uint8)).write(f"{DIR}/bumps.png")
    mi.Bitmap(np.round(normals() * 255).astype(np.uint8)).write(f"{DIR}/normals.png")
    texels = uv_grid()
    mi.Bitmap(np.round(texels * 255).astype(np.uint8)).write(f"{DIR}/uv_grid.png")
    mi.Bitmap(texels.astype(np.float32)).write(f"{DIR}/uv_grid.exr")
    mi.Bitmap(sky()).write(f"{DIR}/sky.hdr")


# Scenes kept elsewhere than DIR: their folder and the parameters (Mitsuba's
# -D) they are rendered with.
ELSEWHERE = {"studio": ("scenes", {"resx": "80", "resy": "60"})}


def render(name, spp):
    folder, parameters = ELSEWHERE.get(name, (DIR, {}))
    text = open(f"{folder}/{name}.xml").read()
    mi.file_resolver().prepend(folder)
    scene = mi.load_string(text.replace("$spp", str(spp)), **parameters)
    started = time.time()
    image = np.array(mi.render(scene, seed=0))
    print(f"{name}: mitsuba {mi.__version__}, {spp} spp in {time.time() - started:.1f} s; mean {image.mean():.5f}")
    mi.Bitmap(image.astype(np.float32)).write(f"{DIR}/{name}_mitsuba.exr")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16384)
    ap.add_argument("--assets", action="store_true", help="write the images the scenes read first")
    ap.add_argument("scenes", nargs="*", help="scene names in tests/data/mitsuba (without .xml), or studio")
    args = ap.parse_args()
    if args.assets:
        write_assets()
    for name in args.scenes:
        render(name, args.spp)


if __name__ == "__main__":
    main()
