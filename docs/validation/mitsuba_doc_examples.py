#!/usr/bin/env python3
"""How many of Mitsuba 3's own documentation examples load here strictly.

Every `.. code-tab:: xml` example in the plugin sources of a Mitsuba 3
checkout (BSDFs, emitters, shapes, textures, sensors, filters, integrators,
spectra, media, phase functions, volumes) is wrapped into a small scene by
its root element: a BSDF or texture on a sphere, an area emitter on a
rectangle, other emitters and shapes beside a floor, a sensor, filter or
integrator in place of the default ones, all under a constant environment
and a perspective camera. Files the examples name (images, meshes, volumes,
spectra) are written as small stand-ins. Mitsuba 3 (`scalar_rgb`) loads each
wrapped scene; for those it loads, `bmc-irradiance render` loads it strictly
(1 spp, path tracing), and the script prints the counts and each refusal.
It measures loading only, not agreement of the images.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository
root, with a built binary and a Mitsuba 3 source tree:

    python docs/validation/mitsuba_doc_examples.py /path/to/mitsuba3 target/debug/bmc-irradiance
"""

import collections
import os
import re
import subprocess
import sys
import tempfile

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

FOLDERS = ["bsdfs", "emitters", "shapes", "textures", "sensors", "rfilters", "films",
           "integrators", "spectra", "media", "phase", "volumes"]
SENSOR = """<sensor type="perspective"><float name="fov" value="40"/>
  <transform name="to_world"><lookat origin="0, 1, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
  <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/>{rfilter}</film>
</sensor>"""
FLOOR = """<shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/>
  <scale value="4"/><translate y="-1"/></transform></shape>"""
LIGHT = """<emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>"""


def examples(root):
    for folder in FOLDERS:
        path = os.path.join(root, "src", folder)
        if not os.path.isdir(path):
            continue
        for name in sorted(os.listdir(path)):
            if not name.endswith(".cpp"):
                continue
            lines = open(os.path.join(path, name), encoding="utf-8").read().splitlines()
            for i, line in enumerate(lines):
                if "code-tab:: xml" not in line:
                    continue
                indent = len(line) - len(line.lstrip()) + 4
                block = []
                for body in lines[i + 1:]:
                    if body.strip() and len(body) - len(body.lstrip()) < indent:
                        break
                    if body.strip().startswith(":name:"):
                        continue
                    block.append(body[indent:] if body.strip() else "")
                text = "\n".join(block).strip()
                if text.startswith("<"):
                    yield f"{folder}/{name}", text


def wrap(text):
    root = re.search(r"<(\w+)", re.sub(r"<!--.*?-->", "", text, flags=re.S)).group(1)
    rfilter, sensor, body = "", None, ""
    if root == "bsdf":
        body = f'<shape type="sphere">{text}</shape>{FLOOR}{LIGHT}'
    elif root == "texture":
        if 'name="' not in text.split(">")[0]:
            text = text.replace("<texture ", '<texture name="reflectance" ', 1)
        body = f'<shape type="sphere"><bsdf type="diffuse">{text}</bsdf></shape>{FLOOR}{LIGHT}'
    elif root == "emitter" and 'type="area"' in text.split(">")[0]:
        body = f'<shape type="rectangle">{text}</shape>{FLOOR}'
    elif root in ("emitter", "shape"):
        body = f"{text}{FLOOR}" + (LIGHT if root == "shape" else "")
    elif root == "sensor":
        sensor, body = text, f"{FLOOR}{LIGHT}"
    elif root == "rfilter":
        rfilter, body = text, f"{FLOOR}{LIGHT}"
    elif root == "film":
        sensor = SENSOR.replace("<film", "<!--").replace("</film>", "-->").format(rfilter="")
        sensor = sensor.replace("</sensor>", text + "</sensor>")
        body = f"{FLOOR}{LIGHT}"
    elif root in ("integrator", "scene"):
        body = f"{text}{FLOOR}{LIGHT}" if root == "integrator" else None
    elif root == "spectrum":
        named = text.replace("<spectrum ", '<spectrum name="reflectance" ', 1)
        body = f'<shape type="sphere"><bsdf type="diffuse">{named}</bsdf></shape>{FLOOR}{LIGHT}'
    else:  # media, phase functions, volumes: inside a shape's interior
        body = f'<shape type="sphere"><bsdf type="null"/>{text}</shape>{FLOOR}{LIGHT}'
    if body is None:
        return root, text
    sensor = sensor or SENSOR.format(rfilter=rfilter)
    return root, f'<scene version="3.0.0">\n{sensor}\n{body}\n</scene>\n'


def stand_ins(directory, text):
    """Small files for every file name the example gives."""
    for name in re.findall(r'name="filename"\s+value="([^"]+)"|filename="([^"]+)"', text):
        name = name[0] or name[1]
        path = os.path.join(directory, name)
        os.makedirs(os.path.dirname(path) or directory, exist_ok=True)
        ext = name.rsplit(".", 1)[-1].lower()
        if ext in ("png", "jpg", "jpeg", "exr", "hdr", "bmp", "tga"):
            mi.Bitmap(np.full((8, 16, 3), 0.5, dtype=np.float32 if ext in ("exr", "hdr") else np.uint8)
                      if ext in ("exr", "hdr") else np.full((8, 16, 3), 128, dtype=np.uint8)).write(path)
        elif ext == "obj":
            open(path, "w").write("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n")
        elif ext == "ply":
            mesh = mi.Mesh("m", 4, 2)
            params = mi.traverse(mesh)
            params["vertex_positions"] = [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0]
            params["faces"] = [0, 1, 2, 0, 2, 3]
            params.update()
            mesh.write_ply(path)
        elif ext == "spd":
            open(path, "w").write("400 0.5\n700 0.5\n")


def main():
    mitsuba_root, binary = sys.argv[1], sys.argv[2]
    counts = collections.Counter()
    refusals = []
    for source, text in examples(mitsuba_root):
        root, scene = wrap(text)
        with tempfile.TemporaryDirectory() as d:
            stand_ins(d, text)
            path = os.path.join(d, "scene.xml")
            open(path, "w").write(scene)
            try:
                mi.load_file(path)
            except Exception as e:  # noqa: BLE001 - any refusal counts
                counts["Mitsuba refuses"] += 1
                print(f"  (Mitsuba refuses {source} <{root}>: {str(e).splitlines()[-1][:100]})")
                continue
            out = os.path.join(d, "out.exr")
            run = subprocess.run([binary, "render", "--scene", path, "--method", "path", "--spp", "1",
                                  "--out", out], capture_output=True, text=True)
            if run.returncode == 0:
                counts["loads strictly"] += 1
            else:
                counts["refused here"] += 1
                lines = [line for line in run.stderr.splitlines() if line.strip()]
                # anyhow's chain: the innermost cause is the last line before any backtrace.
                chain = [line.strip() for line in lines if not line.startswith("Stack backtrace")]
                message = next((line for line in chain if "not supported" in line), chain[-1] if chain else "?")
                refusals.append((source, root, message[:160]))
    print(dict(counts))
    for source, root, message in refusals:
        print(f"{source} <{root}>: {message}")


if __name__ == "__main__":
    main()
