"""Subsurface transfer through the add-on: a thin wax slab lit from behind glows, a thick one does not."""

import bpy
import numpy as np

from node_setups import principled_material
from prt_addon.blender import storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import shading
from prt_addon.core.bake import BakeSettings
from test_bake_blender import add_mesh

MEAN_FREE_PATH = 0.2


def slab(name, thickness):
    """Two 2 × 2 grids facing away from each other, `thickness` apart: top at z = thickness facing +Z,
    bottom at z = 0 facing −Z, with a wax-like subsurface material."""
    ticks = np.linspace(-1.0, 1.0, 11)
    top = [(x, y, thickness) for y in ticks for x in ticks]
    bottom = [(x, y, 0.0) for y in ticks for x in ticks]
    quads = [(r * 11 + c, r * 11 + c + 1, (r + 1) * 11 + c + 1, (r + 1) * 11 + c) for r in range(10) for c in range(10)]
    faces = quads + [tuple(121 + i for i in reversed(q)) for q in quads]
    ob = add_mesh(name, top + bottom, faces)
    ob.data.materials.append(principled_material(f"{name} wax", **{
        "Subsurface Weight": 1.0, "Subsurface Radius": (1.0, 1.0, 1.0), "Subsurface Scale": MEAN_FREE_PATH}))
    return ob


def glow_on_top(ob):
    """Mean radiance of the top face under a unit sun straight below."""
    transfer, meta = storage.read_transfer(ob.data)
    light = np.tile(shading.sun_coefficients(meta["order"], [0.0, 0.0, -1.0], 0.0, 1.0), (3, 1))
    radiance = 0.8 * shading.shade(transfer, light)
    top = np.array([v.co.z for v in ob.data.vertices]) > 0
    return radiance[top].mean(), radiance[~top].mean()


def bake_glow(names, weight):
    for name in names:
        principled = next(n for n in bpy.data.objects[name].active_material.node_tree.nodes
                          if n.type == "BSDF_PRINCIPLED")
        principled.inputs["Subsurface Weight"].default_value = weight
    scene_bake = SceneBake(bpy.context, BakeSettings(order=3, samples=64, seed=7), names)
    scene_bake.run(log=lambda line: None)
    return scene_bake, {name: glow_on_top(bpy.data.objects[name]) for name in names}


def test_thin_slab_lit_from_behind_glows_and_a_thick_one_does_not(empty_scene):
    """Top-face radiance under a sun straight below, with subsurface minus without (same seed, same rays): what
    came through the slab. Without subsurface the top still shows the order-3 sun's ringing, which cancels."""
    slab("Thin", 0.5 * MEAN_FREE_PATH)
    slab("Thick", 10 * MEAN_FREE_PATH).location.x = 5.0
    scene_bake, wax = bake_glow(["Thin", "Thick"], 1.0)
    assert sorted(scene_bake.report().as_dict()["subsurface_objects"]) == ["Thick", "Thin"]
    _, plain = bake_glow(["Thin", "Thick"], 0.0)
    through_thin = wax["Thin"][0] - plain["Thin"][0]
    through_thick = wax["Thick"][0] - plain["Thick"][0]
    lit_bottom = plain["Thin"][1]
    assert np.isfinite([through_thin, through_thick]).all()
    assert through_thin > 0.05 * lit_bottom            # transmitted through half a mean free path
    # Ten mean free paths: almost nothing; what is left is the top face spreading its own (ringing) light.
    assert abs(through_thick) < 0.02 * through_thin
