#!/usr/bin/env python3
"""Render the Cornell box of tests/validation/mitsuba_cornell.py with Blender Cycles (CPU).

  .venv/bin/python bench/cycles_cornell.py --spp 64 --out img.exr [--resolution 256x256]
        [--threads 2] [--seed 0] [--bounces 6] [--no-warmup]

Runs in the `bpy` package (Blender as a Python module), not in a Blender binary.
The scene is built here from the numbers of Mitsuba 3.9.1's `mi.cornell_box()`
(python/mitsuba/__init__.py of Mitsuba 3; the same numbers as our scenes/cornell-box.json):
the same [-1,1]^3 box open towards the camera, the same two boxes, the same diffuse
albedos (Cycles' Diffuse BSDF with roughness 0 is Lambertian), the same 0.46 x 0.38
rectangle light under the ceiling, emitting radiance (18.387, 13.9873, 6.75357) from its
front (downward) side only, and the same pinhole camera (position (0, 0, 3.9), looking
at the origin, 39.3077 degrees on the smaller axis).

What is set so that the image is the same one as Mitsuba's and ours:
  * one-sided light: Mitsuba's area emitter and diffuse BSDF are one-sided, Cycles'
    emission and Diffuse BSDF two-sided, so the light's material is emission + white
    diffuse on its front and a black absorber on its back (Geometry.Backfacing), and its
    light sampling is restricted to the front (emission_sampling FRONT);
  * path length: our max depth 8 = Mitsuba's max_depth 8 = at most 8 segments from the
    camera to the light, i.e. at most 7 scattering vertices. Cycles counts bounces
    after the first hit: max_bounces 0 is direct lighting only (1 scattering vertex), so
    7 vertices is max_bounces = 6 (total and diffuse; glossy and transmission the same).
    --bounces changes it; the bench checks the image mean against Mitsuba's;
  * clamping off (direct and indirect), filter glossy 0, caustics on;
  * pixel filter BOX of width 1 pixel (a pixel is the plain mean of its samples);
  * adaptive sampling off, denoising off, light threshold 0, a black world;
  * CPU device, a fixed thread count, one tile (auto tiling off). Persistent data is
    off: with it on, bpy 5.0.1 answered the timed render with the 1-spp warm-up's
    result (no work done, 1-spp noise), so the timed render syncs the scene again and
    builds its BVH again (36 triangles: milliseconds).
Left at Cycles' defaults and reported in the JSON: the sampling pattern (Cycles' own
low-discrepancy sequence, where Mitsuba and we use independent random numbers: part of
its noise per sample), the light tree (on; MIS between light and BSDF sampling is always
on in Cycles' path tracer) and its Russian roulette (from the first bounce on throughput,
where ours and Mitsuba's start at depth 5).

Timing: a 1-spp render first, untimed (kernel set-up, BVH build, scene sync), then the
timed render: `seconds` is the wall time of bpy.ops.render.render() alone, not the
import, the scene building or writing the image. Cycles' own figure for the render is
reported too (render_time from the render stats, when it can be read).

Output: float32 RGB OpenEXR (--out), linear Rec.709 as Mitsuba's, and one JSON line on
stdout: {"samples": ..., "seconds": ..., "samples_per_second": ..., ...}.
"""

import argparse
import json
import math
import os
import sys
import time

# The WxH parser the Mitsuba side uses, so both renderers read --resolution alike.
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "validation"))
from mitsuba_cornell import parse_resolution  # noqa: E402

# Mitsuba 3.9.1 mi.cornell_box(): albedos, light radiance, camera.
WHITE = (0.885809, 0.698859, 0.666422)
GREEN = (0.105421, 0.37798, 0.076425)
RED = (0.570068, 0.0430135, 0.0443706)
LIGHT_RADIANCE = (18.387, 13.9873, 6.75357)
CAMERA_POSITION = (0.0, 0.0, 3.9)
CAMERA_FOV_DEG = 39.3077

# Shapes as (kind, material, translate, [(axis, degrees), ...], scale), applied as
# translate * rotate * scale to Mitsuba's unit rectangle ([-1,1]^2 at z=0, normal +z)
# or unit cube ([-1,1]^3, outward normals): the to_world of each shape of cornell_box().
SHAPES = [
    ("rectangle", "white", (0, -1, 0), [("x", -90)], (1, 1, 1)),         # floor
    ("rectangle", "white", (0, 1, 0), [("x", 90)], (1, 1, 1)),           # ceiling
    ("rectangle", "white", (0, 0, -1), [], (1, 1, 1)),                   # back
    ("rectangle", "green", (1, 0, 0), [("y", -90)], (1, 1, 1)),          # green wall
    ("rectangle", "red", (-1, 0, 0), [("y", 90)], (1, 1, 1)),            # red wall
    ("cube", "white", (0.335, -0.7, 0.38), [("y", -17)], (0.3, 0.3, 0.3)),       # small box
    ("cube", "white", (-0.33, -0.4, -0.28), [("y", 18.25)], (0.3, 0.61, 0.3)),   # large box
    ("rectangle", "light", (0, 0.99, 0.01), [("x", 90)], (0.23, 0.19, 0.19)),    # light
]


def rotation(axis, degrees):
    """Right-handed rotation matrix (3x3, row-major), as Mitsuba's Transform.rotate."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    if axis == "x":
        return ((1, 0, 0), (0, c, -s), (0, s, c))
    if axis == "y":
        return ((c, 0, s), (0, 1, 0), (-s, 0, c))
    if axis == "z":
        return ((c, -s, 0), (s, c, 0), (0, 0, 1))
    raise ValueError(f"bad axis {axis!r}")


def matmul3(a, b):
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3))
                 for i in range(3))


def apply(m, v):
    return tuple(sum(m[i][k] * v[k] for k in range(3)) for i in range(3))


UNIT_RECT = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]  # counter-clockwise from +z


def shape_quads(kind, translate, rotations, scale):
    """The shape's quads in world space, each counter-clockwise seen from its front."""
    if kind == "rectangle":
        local = [[tuple(p) for p in UNIT_RECT]]
    elif kind == "cube":
        # Each face: the unit rectangle moved to z=1, then turned to its side.
        faces = [[], [("x", 180)], [("x", -90)], [("x", 90)], [("y", 90)], [("y", -90)]]
        local = []
        for rots in faces:
            r = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
            for axis, deg in rots:
                r = matmul3(r, rotation(axis, deg))
            local.append([apply(r, (x, y, 1)) for x, y, _ in UNIT_RECT])
    else:
        raise ValueError(f"bad shape {kind!r}")
    r = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    for axis, deg in rotations:
        r = matmul3(r, rotation(axis, deg))
    quads = []
    for quad in local:
        world = []
        for p in quad:
            q = apply(r, (p[0] * scale[0], p[1] * scale[1], p[2] * scale[2]))
            world.append(tuple(q[i] + translate[i] for i in range(3)))
        quads.append(world)
    return quads


def quad_normal(quad):
    a, b, c = quad[0], quad[1], quad[2]
    u = [b[i] - a[i] for i in range(3)]
    v = [c[i] - a[i] for i in range(3)]
    n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    length = math.sqrt(sum(x * x for x in n))
    return tuple(x / length for x in n)


def try_set(obj, name, value, log):
    """Set obj.name = value if this Blender version has it; log what was done."""
    if hasattr(obj, name):
        setattr(obj, name, value)
        log[name] = value if isinstance(value, (int, float, str, bool)) else str(value)
        return True
    log[name] = "absent in this Blender"
    return False


def diffuse_material(bpy, name, rgb):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*rgb, 1.0)
    d.inputs["Roughness"].default_value = 0.0
    nt.links.new(d.outputs["BSDF"], out.inputs["Surface"])
    return mat


def light_material(bpy, log):
    """Front: emission of LIGHT_RADIANCE plus white diffuse; back: black (one-sided)."""
    mat = bpy.data.materials.new("light")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    emit = nt.nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (*LIGHT_RADIANCE, 1.0)
    emit.inputs["Strength"].default_value = 1.0
    white = nt.nodes.new("ShaderNodeBsdfDiffuse")
    white.inputs["Color"].default_value = (*WHITE, 1.0)
    white.inputs["Roughness"].default_value = 0.0
    front = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(emit.outputs["Emission"], front.inputs[0])
    nt.links.new(white.outputs["BSDF"], front.inputs[1])
    black = nt.nodes.new("ShaderNodeBsdfDiffuse")
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(geo.outputs["Backfacing"], mix.inputs["Fac"])
    nt.links.new(front.outputs["Shader"], mix.inputs[1])   # Fac 0: front face
    nt.links.new(black.outputs["BSDF"], mix.inputs[2])     # Fac 1: back face
    nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    cyc = getattr(mat, "cycles", None)
    if cyc is not None:
        try_set(cyc, "emission_sampling", "FRONT", log.setdefault("light_material", {}))
    return mat


def build_scene(bpy, args, log):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    w, h = args.resolution

    mats = {"white": diffuse_material(bpy, "white", WHITE),
            "green": diffuse_material(bpy, "green", GREEN),
            "red": diffuse_material(bpy, "red", RED),
            "light": light_material(bpy, log)}
    for i, (kind, mat, translate, rotations, scale) in enumerate(SHAPES):
        quads = shape_quads(kind, translate, rotations, scale)
        verts, faces = [], []
        for quad in quads:
            faces.append(tuple(range(len(verts), len(verts) + 4)))
            verts.extend(quad)
        mesh = bpy.data.meshes.new(f"shape{i}")
        mesh.from_pydata(verts, [], faces)
        mesh.update()
        mesh.materials.append(mats[mat])
        obj = bpy.data.objects.new(f"shape{i}", mesh)
        scene.collection.objects.link(obj)
        if mat == "light":
            log["light_normal"] = [round(x, 6) for x in quad_normal(quads[0])]

    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens_unit = "FOV"
    cam_data.sensor_fit = "AUTO" if w == h else ("VERTICAL" if w > h else "HORIZONTAL")
    cam_data.angle = math.radians(CAMERA_FOV_DEG)  # on the smaller axis, as Mitsuba's
    cam_data.clip_start = 0.001
    cam_data.clip_end = 100.0
    cam = bpy.data.objects.new("camera", cam_data)
    # Blender's camera looks down its local -z with +y up: at (0,0,3.9) unrotated it
    # looks at the origin with +y up and +x to the right (red wall, x=-1, on the left).
    cam.location = CAMERA_POSITION
    cam.rotation_euler = (0.0, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        bg.inputs["Strength"].default_value = 0.0
    scene.world = world

    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.threads_mode = "FIXED"
    r.threads = args.threads
    r.use_persistent_data = False
    r.film_transparent = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "32"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0

    c = scene.cycles
    clog = log.setdefault("cycles", {})
    c.device = "CPU"
    c.samples = args.spp
    for name, value in [
            ("use_adaptive_sampling", False), ("use_denoising", False),
            ("use_preview_denoising", False),
            ("max_bounces", args.bounces), ("diffuse_bounces", args.bounces),
            ("glossy_bounces", args.bounces), ("transmission_bounces", args.bounces),
            ("volume_bounces", 0), ("transparent_max_bounces", args.bounces),
            ("min_light_bounces", 0), ("min_transparent_bounces", 0),
            ("sample_clamp_direct", 0.0), ("sample_clamp_indirect", 0.0),
            ("blur_glossy", 0.0), ("caustics_reflective", True),
            ("caustics_refractive", True),
            ("pixel_filter_type", "BOX"), ("filter_width", 1.0),
            ("light_sampling_threshold", 0.0),
            ("seed", args.seed), ("use_animated_seed", False),
            ("use_auto_tile", False)]:
        try_set(c, name, value, clog)
    for name in ("sampling_pattern", "use_light_tree", "film_exposure"):
        clog[name] = getattr(c, name, "absent in this Blender")
    return scene


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--resolution", type=parse_resolution, default=(256, 256))
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--bounces", type=int, default=6,
                    help="Cycles max bounces (6 = max depth 8: see the module doc)")
    ap.add_argument("--no-warmup", action="store_true",
                    help="skip the untimed 1-spp render before the timed one")
    ap.add_argument("--out", required=True, help="output .exr path")
    args = ap.parse_args(argv)
    if args.spp < 1 or args.threads < 1 or args.bounces < 0:
        ap.error("--spp and --threads must be positive, --bounces non-negative")

    import bpy

    log = {}
    scene = build_scene(bpy, args, log)

    warmup_seconds = None
    if not args.no_warmup:
        scene.cycles.samples = 1
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        warmup_seconds = time.perf_counter() - t0
        scene.cycles.samples = args.spp

    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    seconds = time.perf_counter() - t0

    out_dir = os.path.dirname(os.path.abspath(args.out))
    os.makedirs(out_dir, exist_ok=True)
    bpy.data.images["Render Result"].save_render(filepath=os.path.abspath(args.out),
                                                 scene=scene)
    w, h = args.resolution
    samples = w * h * args.spp
    print(json.dumps({
        "samples": samples,
        "seconds": seconds,
        "samples_per_second": samples / seconds if seconds > 0 else None,
        "renderer": "cycles",
        "blender_version": bpy.app.version_string,
        "device": "CPU",
        "resolution": [w, h],
        "spp": args.spp,
        "seed": args.seed,
        "threads": args.threads,
        "bounces": args.bounces,
        "warmup_seconds": warmup_seconds,
        "settings": log,
        "output": args.out,
    }), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
