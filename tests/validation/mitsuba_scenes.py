"""Our built-in scenes as Mitsuba 3 scene dictionaries (film, sampler, integrator apart).

  cornell-box       mi.cornell_box() unchanged: scenes/cornell-box.json is a copy of it.
  cornell-caustics  scenes/cornell-caustics.json: cornell_box() with the two boxes
                    replaced by analytic spheres (Mitsuba `sphere`, as our spheres are
                    Embree's analytic ones, not meshes) and a smaller, brighter light.

Every number of cornell-caustics is the one in scenes/cornell-caustics.json; the
validation (tests/validation/run.sh's caustics check) is what says they still agree.
Materials: our `dielectric` (ior 1.5, smooth, Fresnel-weighted choice of reflection or
refraction, radiance scaled by 1/eta^2 on refraction) is Mitsuba's `dielectric` with
int_ior 1.5 / ext_ior 1.0; our `mirror` (reflectance 1) is Mitsuba's `conductor` with
material "none" (a perfect mirror, reflectance 1 at every angle).
"""

SCENES = ("cornell-box", "cornell-caustics")

# scenes/cornell-caustics.json
GLASS_SPHERE = {"center": [-0.4, -0.6, -0.2], "radius": 0.4}
MIRROR_SPHERE = {"center": [0.45, -0.65, 0.3], "radius": 0.35}
# A quarter of the box's light area (half of each side) at four times its radiance.
CAUSTICS_LIGHT_SCALE = [0.115, 0.095, 0.19]
CAUSTICS_LIGHT_RADIANCE = [73.548, 55.9492, 27.01428]


def cornell_caustics(mi):
    scene = mi.cornell_box()
    del scene["small-box"], scene["large-box"]
    scene["glass-sphere"] = {
        "type": "sphere", **GLASS_SPHERE,
        "bsdf": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0}}
    scene["mirror-sphere"] = {
        "type": "sphere", **MIRROR_SPHERE,
        "bsdf": {"type": "conductor", "material": "none"}}
    # cornell_box()'s light is translate(0, 0.99, 0.01) * rotate(x, 90) * scale(0.23,
    # 0.19, 0.19); the same chain with the smaller scale, as our JSON writes it.
    light = scene["light"]
    light["to_world"] = (mi.ScalarTransform4f().translate([0.0, 0.99, 0.01])
                         .rotate([1.0, 0.0, 0.0], 90.0).scale(CAUSTICS_LIGHT_SCALE))
    light["emitter"]["radiance"] = {"type": "rgb", "value": CAUSTICS_LIGHT_RADIANCE}
    return scene


def scene_dict(mi, name):
    """The scene `name` (one of SCENES) as a dictionary for mi.load_dict()."""
    if name == "cornell-box":
        return mi.cornell_box()
    if name == "cornell-caustics":
        return cornell_caustics(mi)
    raise ValueError(f"unknown scene {name!r} (have {', '.join(SCENES)})")
