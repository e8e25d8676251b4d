"""Render golden light curves with real Blender (Cycles, CPU, headless).

Run with Blender as a Python module, in its own environment:

    python -m venv .bpy && .bpy/bin/pip install "numpy==1.26.*" "bpy==4.5.*"
    .bpy/bin/python blender/render_golden.py blender/scenes/NAME.json tests/golden/NAME.txt

The scene file (written by blender/make_scenes.py from jaxppo's own System,
so a golden checks the whole chain from orbit to flux) gives the star's I(mu)
on a uniform mu grid, and per frame the planets' sky positions (x, y, z) and
radii. Set-up, after Mueller et al. (2021, Sect. 2.5):

* the star: a flat disk facing the camera whose emission is I(mu), mu
  computed in the shader from the object coordinates (r^2 = x^2 + y^2) and
  looked up in a 1D float texture with linear interpolation;
* planets: opaque disks with zero emission (black), no light bounces, so they
  reflect nothing; polygons with 1024 vertices whose radius is scaled so that
  their area is exactly pi r^2 (the star's outline likewise);
* an orthographic camera on the z axis, ortho scale 2 (the star fills the
  N x N frame), the Box pixel filter (Blackman-Harris would blur the limb,
  paper Sect. 2.5), no denoising, a fixed seed, linear float EXR output,
  the "Raw" view transform;
* flux = pixel sum normalised by an unocculted frame. Only the region around
  the planets is rendered (border rendering): the rest of the frame equals the
  unocculted render, whose pixel sum is reused.
"""

from __future__ import annotations

import datetime
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import bpy
import numpy as np


def ngon_radius(r, n):
    """Circumradius of a regular n-gon with the area of a circle of radius r."""
    return r * math.sqrt(math.pi / (0.5 * n * math.sin(2 * math.pi / n)))


def setup(scene_spec):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = int(scene_spec["samples"])
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.use_denoising = False
    sc.cycles.seed = int(scene_spec.get("seed", 0))
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.max_bounces = 0
    sc.view_settings.view_transform = "Raw"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    n = int(scene_spec["resolution"])
    sc.render.resolution_x = sc.render.resolution_y = n
    sc.render.resolution_percentage = 100
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.color_mode = "RGBA"
    sc.render.film_transparent = True  # alpha marks the rendered region of a border render
    world = bpy.data.worlds.new("black")
    world.color = (0.0, 0.0, 0.0)
    sc.world = world

    # the star: a flat disk with emission I(mu)
    mu_grid = np.asarray(scene_spec["star"]["mu"], float)
    inten = np.asarray(scene_spec["star"]["intensity"], float)
    m = mu_grid.size
    tex = bpy.data.images.new("profile", width=m, height=1, float_buffer=True, alpha=False)
    tex.colorspace_settings.name = "Non-Color"  # before the pixels: changing it reloads the buffer
    rgba = np.zeros((m, 4), np.float32)
    rgba[:, 0] = rgba[:, 1] = rgba[:, 2] = inten
    rgba[:, 3] = 1.0
    tex.pixels.foreach_set(rgba.ravel())
    tex.update()
    back = np.empty(m * 4, np.float32)
    tex.pixels.foreach_get(back)
    if not np.allclose(back.reshape(m, 4)[:, 0], inten, rtol=0, atol=1e-6):
        raise RuntimeError("the intensity texture did not take its pixels")
    bpy.ops.mesh.primitive_circle_add(vertices=2048, radius=ngon_radius(1.0, 2048), fill_type="NGON", location=(0, 0, 0))
    star = bpy.context.active_object
    mat = bpy.data.materials.new("star")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    N = nt.nodes.new
    L = nt.links.new
    coord = N("ShaderNodeTexCoord")
    sep = N("ShaderNodeSeparateXYZ")
    L(coord.outputs["Object"], sep.inputs[0])
    x2 = N("ShaderNodeMath"); x2.operation = "MULTIPLY"
    L(sep.outputs[0], x2.inputs[0]); L(sep.outputs[0], x2.inputs[1])
    y2 = N("ShaderNodeMath"); y2.operation = "MULTIPLY"
    L(sep.outputs[1], y2.inputs[0]); L(sep.outputs[1], y2.inputs[1])
    r2 = N("ShaderNodeMath"); r2.operation = "ADD"
    L(x2.outputs[0], r2.inputs[0]); L(y2.outputs[0], r2.inputs[1])
    one_minus = N("ShaderNodeMath"); one_minus.operation = "SUBTRACT"
    one_minus.inputs[0].default_value = 1.0
    L(r2.outputs[0], one_minus.inputs[1])
    clamp = N("ShaderNodeMath"); clamp.operation = "MAXIMUM"
    clamp.inputs[1].default_value = 0.0
    L(one_minus.outputs[0], clamp.inputs[0])
    mu = N("ShaderNodeMath"); mu.operation = "SQRT"
    L(clamp.outputs[0], mu.inputs[0])
    # texel centres: u = (mu (m - 1) + 0.5) / m
    scale = N("ShaderNodeMath"); scale.operation = "MULTIPLY_ADD"
    scale.inputs[1].default_value = (m - 1) / m
    scale.inputs[2].default_value = 0.5 / m
    L(mu.outputs[0], scale.inputs[0])
    comb = N("ShaderNodeCombineXYZ")
    comb.inputs[1].default_value = 0.5
    L(scale.outputs[0], comb.inputs[0])
    img = N("ShaderNodeTexImage")
    img.image = tex
    img.interpolation = "Linear"
    img.extension = "EXTEND"
    L(comb.outputs[0], img.inputs["Vector"])
    em = N("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0
    L(img.outputs["Color"], em.inputs["Color"])
    out = N("ShaderNodeOutputMaterial")
    L(em.outputs[0], out.inputs[0])
    star.data.materials.append(mat)

    black = bpy.data.materials.new("planet")
    black.use_nodes = True
    bn = black.node_tree
    bn.nodes.clear()
    bem = bn.nodes.new("ShaderNodeEmission")
    bem.inputs["Strength"].default_value = 0.0
    bem.inputs["Color"].default_value = (0, 0, 0, 1)
    bout = bn.nodes.new("ShaderNodeOutputMaterial")
    bn.links.new(bem.outputs[0], bout.inputs[0])

    k = max(len(f["disks"]) for f in scene_spec["frames"])
    planets = []
    for _ in range(k):
        bpy.ops.mesh.primitive_circle_add(vertices=1024, radius=ngon_radius(1.0, 1024), fill_type="NGON", location=(5, 5, 1))
        pl = bpy.context.active_object
        pl.data.materials.append(black)
        planets.append(pl)

    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.0
    cam_data.clip_start = 0.01
    cam_data.clip_end = 10000.0
    cam = bpy.data.objects.new("camera", cam_data)
    sc.collection.objects.link(cam)
    cam.location = (0.0, 0.0, 1000.0)
    sc.camera = cam
    return sc, planets, n


def render(sc, path, border=None):
    """Render to EXR and return (red, alpha) as [row, col] arrays (row 0 at the
    bottom, as Blender stores it). With ``border`` = (col0, col1, row0, row1)
    only that region is rendered; the image keeps its full size and alpha is 0
    outside what was rendered (and on the empty sky, which adds nothing)."""
    sc.render.use_border = border is not None
    sc.render.use_crop_to_border = False
    if border is not None:
        n = sc.render.resolution_x
        c0, c1, r0, r1 = border
        sc.render.border_min_x, sc.render.border_max_x = c0 / n, c1 / n
        sc.render.border_min_y, sc.render.border_max_y = r0 / n, r1 / n
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    px = px.reshape(h, w, 4).astype(np.float64)
    alpha = np.nan_to_num(px[..., 3])
    # un-premultiplying empty pixels gives 0/0: they hold no light
    red = np.where(alpha > 0, np.nan_to_num(px[..., 0]), 0.0)
    return red, alpha


def main(scene_file, out_file):
    spec = json.loads(Path(scene_file).read_text())
    sc, planets, n = setup(spec)
    tmp = Path(tempfile.mkdtemp(prefix="jaxppo_blender_"))
    for pl in planets:
        pl.hide_render = True
    t_start = time.time()
    full, _ = render(sc, tmp / "unocculted.exr")
    full_frame_seconds = time.time() - t_start
    total = full.sum()
    pix = 2.0 / n
    rows = []
    n_rendered = 0
    for fi, frame in enumerate(spec["frames"]):
        on = []
        for pl, (x, y, z, r) in zip(planets, frame["disks"]):
            visible = z > 0 and r > 0 and math.hypot(x, y) - r < 1.0
            pl.hide_render = not visible
            if visible:
                rr = ngon_radius(r, 1024)
                pl.location = (x, y, z)
                pl.scale = (rr, rr, 1.0)
                on.append((x, y, r))
        for pl in planets[len(frame["disks"]):]:
            pl.hide_render = True
        if not on:
            rows.append((frame["time"], 1.0))
            continue
        # pixel box around the planets (2 px margin); pixel i spans [-1 + i pix, -1 + (i+1) pix]
        c0 = max(0, int(math.floor((min(x - r for x, _, r in on) + 1.0) / pix)) - 2)
        c1 = min(n, int(math.ceil((max(x + r for x, _, r in on) + 1.0) / pix)) + 2)
        r0 = max(0, int(math.floor((min(y - r for _, y, r in on) + 1.0) / pix)) - 2)
        r1 = min(n, int(math.ceil((max(y + r for _, y, r in on) + 1.0) / pix)) + 2)
        part, alpha = render(sc, tmp / f"f{fi}.exr", (c0, c1, r0, r1))
        done = alpha > 0
        lost = full[done].sum() - part[done].sum()
        rows.append((frame["time"], 1.0 - lost / total))
        n_rendered += 1
    elapsed = time.time() - t_start
    meta = {
        "name": spec["name"],
        "description": spec["description"],
        "blender": bpy.app.version_string,
        "engine": "Cycles (CPU), Box filter, no denoising, no bounces, Raw view, 32-bit EXR",
        "resolution": n,
        "samples": spec["samples"],
        "seed": spec.get("seed", 0),
        "frames": len(rows),
        "frames_rendered": n_rendered,
        "render_seconds": round(elapsed, 2),
        "seconds_per_rendered_frame": round(elapsed / max(n_rendered + 1, 1), 3),
        "full_frame_seconds": round(full_frame_seconds, 3),
        "date": datetime.date.today().isoformat(),
        "scene": spec.get("params", {}),
    }
    lines = [f"# {k}: {json.dumps(v)}" for k, v in meta.items()]
    lines.append("# columns: time flux")
    lines += [f"{t:.8f} {f:.12f}" for t, f in rows]
    Path(out_file).write_text("\n".join(lines) + "\n")
    print(f"{spec['name']}: {len(rows)} frames ({n_rendered} rendered) in {elapsed:.1f} s -> {out_file}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
