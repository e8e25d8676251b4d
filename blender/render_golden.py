"""Render a golden light curve with real Blender (Cycles, CPU, headless),
moving the planets inside Blender from their orbital elements.

Run with Blender as a Python module, in its own environment (nothing from
jaxppo is imported here, and nothing is precomputed by jaxppo):

    python3.11 -m venv .bpy && .bpy/bin/pip install "numpy==1.26.*" "bpy==4.5.*"
    .bpy/bin/python blender/render_golden.py blender/golden_scenes/NAME.json tests/golden/NAME.txt

The scene file (blender/golden_scenes/*.json, written by
blender/make_scenes.py) holds the star's limb-darkening law or (mu, I)
table, each planet's elements (period [d], t0 [d], a [R*], inc [deg],
radius [R*], name), which planet is tilted, alpha [deg], the hemisphere case,
the times [d] and the render settings.

Set-up, after Mueller et al. (2021, Sect. 2.3.2):

* the star: a UV sphere of unit radius at the origin (512 segments; the
  paper used 256) with an emission shader of strength 1 whose colour is the
  intensity profile I(mu). mu = sqrt(1 - x^2 - y^2) is computed in the shader
  from the object coordinates of the point hit (the orthographic camera looks
  along z, so x, y are the sky coordinates); a law is evaluated with math
  nodes, a table through a 1D float texture with linear interpolation (the
  paper interpolated its PHOENIX table linearly). The paper put the profile
  on a filter plane in front of an isotropic sphere; an emission colour on the
  sphere itself gives the same image without the 1 Gpx texture.
* the planets: UV spheres (256 segments) with a black, zero-strength
  emission shader and no light bounces, so they only block light. Meshes are
  polygons, so every sphere is scaled such that its outline (the equator
  polygon, poles on the line of sight) has the area of the circle it stands
  for; blender/silhouette_error.py measures what the polygon edges leave.
* the orbits (circular; CONVENTIONS): phi = 2 pi (t - t0) / P,
  x = a sin(phi), y = a cos(phi) |cos i|, z = a cos(phi) sin(i), observer on
  +z, x right, y up. |cos i| puts every planet on the upper hemisphere, so
  i -> 180 - i changes nothing; case "opposite" mirrors every untilted planet
  (y -> -y). The tilted planet moves in this frame inside a parent Empty whose
  matrix is the paper's R_y(alpha) with the paper's (x, z) = our (x, y):
  x' = x cos(alpha) + y sin(alpha), y' = -x sin(alpha) + y cos(alpha).
  Blender itself applies that matrix (object parenting). A frame-change
  handler sets the positions from the frame's time, so the animation is
  driven inside Blender. Planets behind the star (z < 0) are hidden by the
  star sphere, as in the paper's scene.
* an orthographic camera on the +z axis (ortho scale 2: the star fills the
  N x N frame), the Box pixel filter (Blackman-Harris blurs the limb, paper
  Sect. 2.3.2), no denoising, no adaptive sampling, a fixed seed, the "Raw"
  view transform and 32-bit float EXR output (the paper: 16-bit PNG).
* spots (optional ``"spots"`` in the scene: lat, lon, radius, contrast per
  spot [deg, deg, deg, 1], period [d], inc [deg], t_ref [d], obliquity [deg],
  edge [deg]): an Empty "star_axis" carries the rotation axis (its z axis
  goes to (0, sin i, cos i) on the sky, then the sky rotation by the
  obliquity, the same matrix as alpha's), and its child "star_spin" turns
  about that axis by 2 pi (t - t_ref) / P, set per frame by the handler. The
  star's shader reads the point hit in star_spin's frame (a Texture
  Coordinate node bound to that object: Blender applies the rotation), where
  each spot is a fixed unit vector (cos lat cos lon, -cos lat sin lon,
  sin lat); the emission colour I(mu) is multiplied by
  1 - sum_k c_k S(theta_k), theta_k the angle to spot k (arccos of the dot
  product) and S the cubic smoothstep from 1 at radius - edge/2 to 0 at
  radius + edge/2. A spot's longitude is the rotational phase at which it
  faces the observer.
* flux = pixel sum normalised by the unocculted frame (with spots: the
  unocculted frame of the unspotted star). Only the pixel box
  around the planets in front of the star is rendered (border rendering with a
  transparent film: alpha marks the rendered pixels); outside it the frame
  equals the unocculted render, whose pixel sum is reused (with spots the
  box also holds every spot's cap, so that outside it the frame equals the
  unspotted star's).
"""

from __future__ import annotations

import datetime
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix, Vector

STAR_SEGMENTS = 512
PLANET_SEGMENTS = 256


def ngon_radius(r: float, n: int) -> float:
    """Circumradius of a regular n-gon with the area of a circle of radius r."""
    return r * math.sqrt(math.pi / (0.5 * n * math.sin(2 * math.pi / n)))


# ---- the star's profile, evaluated inside Blender ------------------------------
def law_terms(law: str, c) -> list[tuple[float, float]]:
    """The law as sum_k a_k mu**e_k: list of (a_k, e_k) (CONVENTIONS: quadratic
    I = 1 - u1 (1 - mu) - u2 (1 - mu)^2; non-linear (Claret 2000)
    I = 1 - sum c_k (1 - mu^(k/2)); power-2 I = 1 - c (1 - mu^alpha))."""
    if law == "uniform":
        return [(1.0, 0.0)]
    if law == "quadratic":
        u1, u2 = c
        return [(1.0 - u1 - u2, 0.0), (u1 + 2.0 * u2, 1.0), (-u2, 2.0)]
    if law == "nonlinear":
        return [(1.0 - sum(c), 0.0)] + [(ck, 0.5 * (k + 1)) for k, ck in enumerate(c)]
    if law == "power2":
        cc, al = c
        return [(1.0 - cc, 0.0), (cc, al)]
    raise ValueError(f"unknown law {law!r}")


def star_material(star: dict, spots: dict | None = None, spin=None):
    """The star's emission shader; with ``spots``, the returned material has
    a Value node "spots_on" (1: spotted, 0: bare star)."""
    mat = bpy.data.materials.new("star")
    mat.use_nodes = True
    # seen by camera rays only (no bounces): not a light to sample, which would
    # cost seconds per frame building the emissive-triangle tables
    mat.cycles.emission_sampling = "NONE"
    nt = mat.node_tree
    nt.nodes.clear()
    N, L = nt.nodes.new, nt.links.new

    def math_node(op, a=None, b=None, c=None):
        node = N("ShaderNodeMath")
        node.operation = op
        for k, v in enumerate((a, b, c)):
            if v is None:
                continue
            if isinstance(v, (int, float)):
                node.inputs[k].default_value = float(v)
            else:
                L(v, node.inputs[k])
        return node.outputs[0]

    coord = N("ShaderNodeTexCoord")
    sep = N("ShaderNodeSeparateXYZ")
    L(coord.outputs["Object"], sep.inputs[0])
    x, y = sep.outputs[0], sep.outputs[1]
    r2 = math_node("ADD", math_node("MULTIPLY", x, x), math_node("MULTIPLY", y, y))
    mu = math_node("SQRT", math_node("MAXIMUM", math_node("SUBTRACT", 1.0, r2), 0.0))
    em = N("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0
    if "law" in star:
        total = None
        for a_k, e_k in law_terms(star["law"], star.get("coefficients", [])):
            term = a_k if e_k == 0.0 else math_node("MULTIPLY", math_node("POWER", mu, e_k), a_k)
            if total is None:
                total = math_node("ADD", term, 0.0) if isinstance(term, float) else term
            else:
                total = math_node("ADD", total, term)
        L(total, em.inputs["Color"])
    else:
        # a (mu, I) table, linear between its nodes: resampled (still piecewise
        # linear, exactly at the grid points) onto a uniform grid of M texels
        # read with linear interpolation
        m = 8193
        grid = np.linspace(0.0, 1.0, m)
        inten = np.interp(grid, np.asarray(star["mu"], float), np.asarray(star["intensity"], float))
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
        # texel centres: u = (mu (m - 1) + 0.5) / m
        u = math_node("MULTIPLY_ADD", mu, (m - 1) / m, 0.5 / m)
        comb = N("ShaderNodeCombineXYZ")
        comb.inputs[1].default_value = 0.5
        L(u, comb.inputs[0])
        img = N("ShaderNodeTexImage")
        img.image = tex
        img.interpolation = "Linear"
        img.extension = "EXTEND"
        L(comb.outputs[0], img.inputs["Vector"])
        L(img.outputs["Color"], em.inputs["Color"])
    if spots is not None:
        # the emission colour times 1 - sum_k c_k S_k, in the rotating star frame
        color_link = em.inputs["Color"].links[0]
        base = color_link.from_socket
        nt.links.remove(color_link)
        sc_coord = N("ShaderNodeTexCoord")
        sc_coord.object = spin
        norm = N("ShaderNodeVectorMath")
        norm.operation = "NORMALIZE"
        L(sc_coord.outputs["Object"], norm.inputs[0])
        total = None
        w = math.radians(float(spots["edge"]))
        for lat, lon, rad, c in zip(spots["lat"], spots["lon"], spots["radius"], spots["contrast"]):
            la, lo = math.radians(lat), math.radians(lon)
            dot = N("ShaderNodeVectorMath")
            dot.operation = "DOT_PRODUCT"
            L(norm.outputs[0], dot.inputs[0])
            dot.inputs[1].default_value = (math.cos(la) * math.cos(lo), -math.cos(la) * math.sin(lo), math.sin(la))
            theta = math_node("ARCCOSINE", math_node("MINIMUM", math_node("MAXIMUM", dot.outputs["Value"], -1.0), 1.0))
            u = N("ShaderNodeMath")
            u.operation = "MULTIPLY_ADD"
            u.use_clamp = True  # s in [0, 1]
            L(theta, u.inputs[0])
            u.inputs[1].default_value = -1.0 / w
            u.inputs[2].default_value = math.radians(float(rad)) / w + 0.5
            sv = u.outputs[0]
            smooth = math_node("MULTIPLY", math_node("MULTIPLY", sv, sv), math_node("MULTIPLY_ADD", sv, -2.0, 3.0))
            term = math_node("MULTIPLY", smooth, float(c))
            total = term if total is None else math_node("ADD", total, term)
        on = N("ShaderNodeValue")
        on.name = "spots_on"
        on.outputs[0].default_value = 1.0
        factor = math_node("SUBTRACT", 1.0, math_node("MULTIPLY", total, on.outputs[0]))
        mix = N("ShaderNodeVectorMath")
        mix.operation = "SCALE"
        L(base, mix.inputs[0])
        L(factor, mix.inputs["Scale"])
        L(mix.outputs[0], em.inputs["Color"])
    out = N("ShaderNodeOutputMaterial")
    L(em.outputs[0], out.inputs[0])
    return mat


def spin_frame(spots: dict):
    """Empties star_axis (the rotation axis on the sky) and its child
    star_spin (the rotating star frame)."""
    sc = bpy.context.scene
    i = math.radians(float(spots["inc"]))
    # columns: star x -> the meridian facing the observer (0, -cos i, sin i),
    # star y -> +x on the sky, star z -> the axis (0, sin i, cos i)
    b = Matrix(((0.0, 1.0, 0.0, 0.0), (-math.cos(i), 0.0, math.sin(i), 0.0),
                (math.sin(i), 0.0, math.cos(i), 0.0), (0.0, 0.0, 0.0, 1.0)))
    axis = bpy.data.objects.new("star_axis", None)
    sc.collection.objects.link(axis)
    axis.matrix_basis = tilt_matrix(float(spots.get("obliquity", 0.0))) @ b
    spin = bpy.data.objects.new("star_spin", None)
    sc.collection.objects.link(spin)
    spin.parent = axis
    spin.matrix_parent_inverse = Matrix.Identity(4)
    return spin


def black_material():
    mat = bpy.data.materials.new("planet")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 0.0
    em.inputs["Color"].default_value = (0, 0, 0, 1)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(em.outputs[0], out.inputs[0])
    return mat


def uv_sphere(radius: float, segments: int, name: str, material):
    """A UV sphere (poles on the z axis, ``segments`` meridians, segments / 2
    rings, as Blender's "UV sphere", the paper's mesh) whose outline seen along
    z, the equator polygon, has the area pi radius^2. Built from arrays: the
    operator primitive_uv_sphere_add takes minutes at 1024 segments."""
    n, rings = segments, segments // 2
    lon = 2.0 * np.pi * np.arange(n) / n
    lat = np.pi * np.arange(1, rings) / rings  # polar angle of the inner rings
    ring_xyz = np.stack([np.sin(lat)[:, None] * np.cos(lon)[None, :],
                         np.sin(lat)[:, None] * np.sin(lon)[None, :],
                         np.repeat(np.cos(lat)[:, None], n, 1)], -1).reshape(-1, 3)
    verts = np.concatenate([[[0.0, 0.0, 1.0]], ring_xyz, [[0.0, 0.0, -1.0]]])
    idx = 1 + np.arange((rings - 1) * n).reshape(rings - 1, n)
    nxt = np.roll(idx, -1, axis=1)
    quads = np.stack([idx[:-1], idx[1:], nxt[1:], nxt[:-1]], -1).reshape(-1, 4)
    south = len(verts) - 1
    faces = ([(0, int(a), int(b)) for a, b in zip(idx[0], nxt[0])]
             + [tuple(int(v) for v in q) for q in quads]
             + [(int(a), south, int(b)) for a, b in zip(idx[-1], nxt[-1])])
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts.tolist(), [], faces)
    mesh.validate()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    s = ngon_radius(radius, segments)
    obj.scale = (s, s, s)
    obj.data.materials.append(material)
    return obj


# ---- the orbits (paper Sect. 2.3.2 step 2, CONVENTIONS) ---------------------
def orbit_position(el: dict, t: float, mirror: bool) -> tuple[float, float, float]:
    """Position (x, y, z) [R*] of a circular orbit in the untilted frame:
    upper hemisphere (|cos i|), mirrored (y -> -y) when ``mirror``."""
    phi = 2.0 * math.pi * (t - el["t0"]) / el["period"]
    inc = math.radians(el["inc"])
    a = el["a"]
    y = a * math.cos(phi) * abs(math.cos(inc))
    return a * math.sin(phi), -y if mirror else y, a * math.cos(phi) * math.sin(inc)


def tilt_matrix(alpha_deg: float) -> Matrix:
    """The paper's R_y(alpha) with its (x, z) = our (x, y): x' = x cos + y sin,
    y' = -x sin + y cos, z' = z."""
    al = math.radians(alpha_deg)
    c, s = math.cos(al), math.sin(al)
    return Matrix(((c, s, 0.0, 0.0), (-s, c, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0)))


def setup(spec: dict):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = int(spec["samples"])
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.use_denoising = False
    sc.cycles.seed = int(spec.get("seed", 0))
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.max_bounces = 0
    sc.render.use_persistent_data = True  # keep the star's BVH between frames
    sc.view_settings.view_transform = "Raw"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    n = int(spec["resolution"])
    sc.render.resolution_x = sc.render.resolution_y = n
    sc.render.resolution_percentage = 100
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.color_mode = "RGBA"
    sc.render.film_transparent = True  # alpha marks the rendered region of a border render
    world = bpy.data.worlds.new("black")
    world.color = (0.0, 0.0, 0.0)
    sc.world = world

    spots = spec.get("spots")
    spin = spin_frame(spots) if spots else None
    star_mat = star_material(spec["star"], spots, spin)
    uv_sphere(1.0, STAR_SEGMENTS, "star", star_mat)
    black = black_material()
    tilt = bpy.data.objects.new("tilt", None)  # Empty carrying R_y(alpha)
    sc.collection.objects.link(tilt)
    tilt.matrix_basis = tilt_matrix(float(spec["alpha"]))
    planets = []
    for k, el in enumerate(spec["planets"]):
        pl = uv_sphere(el["radius"], PLANET_SEGMENTS, f"planet_{el.get('name') or k}", black)
        if k == int(spec["tilted"]):
            pl.parent = tilt
            pl.matrix_parent_inverse = Matrix.Identity(4)
        planets.append(pl)

    a_max = max(el["a"] for el in spec["planets"])
    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.0
    cam_data.clip_start = 0.01
    cam_data.clip_end = 4.0 * a_max + 20.0
    cam = bpy.data.objects.new("camera", cam_data)
    sc.collection.objects.link(cam)
    cam.location = (0.0, 0.0, 2.0 * a_max + 10.0)  # identity rotation: looks along -z, y up
    sc.camera = cam

    times = [float(t) for t in spec["times"]]
    tilted, case = int(spec["tilted"]), spec["case"]
    if case not in ("same", "opposite"):
        raise ValueError(f"case must be 'same' or 'opposite', got {case!r}")

    def move_planets(scene, *_):
        t = times[scene.frame_current]
        for k, (pl, el) in enumerate(zip(planets, spec["planets"])):
            pl.location = orbit_position(el, t, mirror=(case == "opposite" and k != tilted))
        if spin is not None:
            spin.rotation_euler = (0.0, 0.0, 2.0 * math.pi * (t - float(spots["t_ref"])) / float(spots["period"]))

    bpy.app.handlers.frame_change_pre.clear()
    bpy.app.handlers.frame_change_pre.append(move_planets)
    sc.frame_start, sc.frame_end = 0, len(times) - 1
    return sc, planets, n


def spots_switch(on: bool) -> None:
    node = bpy.data.materials["star"].node_tree.nodes.get("spots_on")
    if node is not None:
        node.outputs[0].default_value = 1.0 if on else 0.0


def spot_boxes(spec: dict) -> list[tuple[float, float, float]]:
    """(x, y, half size) [R*] on the sky of a square holding each visible
    spot's cap (angular radius radius + edge/2: chord 2 sin(beta/2))."""
    spots = spec.get("spots")
    if not spots:
        return []
    spin = bpy.data.objects["star_spin"]
    out = []
    for lat, lon, rad in zip(spots["lat"], spots["lon"], spots["radius"]):
        la, lo = math.radians(lat), math.radians(lon)
        v = spin.matrix_world.to_3x3() @ Vector((math.cos(la) * math.cos(lo), -math.cos(la) * math.sin(lo), math.sin(la)))
        beta = math.radians(float(rad) + 0.5 * float(spots["edge"]))
        if v.z > -math.sin(beta):  # some of the cap is on the visible side
            out.append((v.x, v.y, 2.0 * math.sin(0.5 * beta)))
    return out


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


def check_orientation(sc, planets, tmp):
    """The image must show x to the right and y up (row 0 at the bottom): a
    planet put at (0.5, 0.3) in front must darken the pixels there. Checked
    at 100 x 100 pixels, 4 samples."""
    n, s = sc.render.resolution_x, sc.cycles.samples
    sc.render.resolution_x = sc.render.resolution_y = 100
    sc.cycles.samples = 4
    saved = [(pl.parent, pl.location.copy(), pl.scale.copy(), pl.hide_render) for pl in planets]
    handlers = list(bpy.app.handlers.frame_change_pre)  # a render calls them: keep them off the test planet
    bpy.app.handlers.frame_change_pre.clear()
    for pl in planets:
        pl.hide_render = True
    full, _ = render(sc, tmp / "orient0.exr")
    pl = planets[0]
    pl.parent = None
    pl.location = (0.5, 0.3, 5.0)
    pl.scale = (0.1, 0.1, 0.1)
    pl.hide_render = False
    part, _ = render(sc, tmp / "orient1.exr")
    deficit = full - part
    rows, cols = np.nonzero(deficit > 0.5 * deficit.max())
    x, y = (cols.mean() + 0.5) / 50.0 - 1.0, (rows.mean() + 0.5) / 50.0 - 1.0
    if abs(x - 0.5) > 0.05 or abs(y - 0.3) > 0.05:
        raise RuntimeError(f"image orientation: planet at (0.5, 0.3) rendered at ({x:.3f}, {y:.3f})")
    for pl, (parent, loc, scale, hide) in zip(planets, saved):
        pl.parent = parent
        pl.matrix_parent_inverse = Matrix.Identity(4)
        pl.location = loc
        pl.scale = scale
        pl.hide_render = hide
    sc.render.resolution_x = sc.render.resolution_y = n
    sc.cycles.samples = s
    bpy.app.handlers.frame_change_pre.extend(handlers)


def main(scene_file, out_file):
    spec = json.loads(Path(scene_file).read_text())
    sc, planets, n = setup(spec)
    tmp = Path(tempfile.mkdtemp(prefix="jaxppo_blender_"))
    spots_switch(False)
    check_orientation(sc, planets, tmp)
    t_start = time.time()
    for pl in planets:
        pl.hide_render = True
    full, _ = render(sc, tmp / "unocculted.exr")
    spots_switch(True)
    full_frame_seconds = time.time() - t_start
    for pl in planets:
        pl.hide_render = False
    total = full.sum()
    pix = 2.0 / n
    radii = [el["radius"] for el in spec["planets"]]
    rows, n_rendered = [], 0
    for fi, t in enumerate(spec["times"]):
        sc.frame_set(fi)  # the handler moves the planets; Blender applies the tilt
        on = []
        for pl, r in zip(planets, radii):
            x, y, z = pl.matrix_world.translation
            if z > 0 and math.hypot(x, y) - r < 1.0:
                on.append((x, y, r))
        on += spot_boxes(spec)  # the spotted star differs from the bare one there
        if not on:
            rows.append((t, 1.0))
            continue
        # pixel box around the planets in front (2 px margin); pixel i spans [-1 + i pix, -1 + (i+1) pix]
        c0 = max(0, int(math.floor((min(x - r for x, _, r in on) + 1.0) / pix)) - 2)
        c1 = min(n, int(math.ceil((max(x + r for x, _, r in on) + 1.0) / pix)) + 2)
        r0 = max(0, int(math.floor((min(y - r for _, y, r in on) + 1.0) / pix)) - 2)
        r1 = min(n, int(math.ceil((max(y + r for _, y, r in on) + 1.0) / pix)) + 2)
        part, alpha = render(sc, tmp / f"f{fi}.exr", (c0, c1, r0, r1))
        done = alpha > 0
        lost = full[done].sum() - part[done].sum()
        rows.append((t, 1.0 - lost / total))
        n_rendered += 1
    elapsed = time.time() - t_start
    scene = {k: spec[k] for k in ("star", "planets", "tilted", "alpha", "case", "spots") if k in spec}
    meta = {
        "name": spec["name"],
        "description": spec["description"],
        "blender": bpy.app.version_string,
        "engine": "Cycles (CPU), Box filter, no denoising, no adaptive sampling, no bounces, Raw view, 32-bit EXR",
        "geometry": f"UV spheres: star {STAR_SEGMENTS} segments, planets {PLANET_SEGMENTS} segments, outlines area-matched; orthographic camera on +z",
        "resolution": n,
        "samples": spec["samples"],
        "seed": spec.get("seed", 0),
        "frames": len(rows),
        "frames_rendered": n_rendered,
        "render_seconds": round(elapsed, 2),
        "seconds_per_rendered_frame": round(elapsed / max(n_rendered + 1, 1), 3),
        "full_frame_seconds": round(full_frame_seconds, 3),
        "date": datetime.date.today().isoformat(),
        "source": spec.get("source", ""),
        "scene": scene,
    }
    lines = [f"# {k}: {json.dumps(v)}" for k, v in meta.items()]
    lines.append("# columns: time flux")
    lines += [f"{t:.10f} {f:.12f}" for t, f in rows]
    Path(out_file).write_text("\n".join(lines) + "\n")
    print(f"{spec['name']}: {len(rows)} frames ({n_rendered} rendered) in {elapsed:.1f} s -> {out_file}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
    sys.stdout.flush()
    os._exit(0)  # bpy's exit-time leak report can stall for minutes
