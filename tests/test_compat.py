"""The version differences blender/compat.py holds, checked on whichever Blender runs the suite (CI runs it on
every version of the matrix), against what that version itself says."""

import bpy

from prt_addon.blender import compat


def test_new_node_material_and_world_have_an_empty_tree(empty_scene):
    for made in (compat.new_node_material("m"), compat.new_node_world("w")):
        assert made.node_tree is not None and len(made.node_tree.nodes) == 0


def test_eevee_engine_id_is_the_one_this_blender_lists_and_renders_with(empty_scene):
    engines = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    assert compat.eevee_engine_id() in engines
    expected = "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"
    assert compat.eevee_engine_id() == expected
    empty_scene.render.engine = compat.eevee_engine_id()
    assert empty_scene.render.engine == expected
