"""Where the Blender versions the extension supports differ, in one place. Each difference is named here and
tested on every version of the test matrix (tests/test_compat.py); everything else is written once for all."""

import bpy


def _emptied(datablock):
    """Before Blender 5.0 new materials and worlds have no node tree until use_nodes is set (5.0 deprecates
    use_nodes: every one has a tree); what a new tree holds differs too, so it starts empty here."""
    if datablock.node_tree is None:
        datablock.use_nodes = True
    datablock.node_tree.nodes.clear()
    return datablock


def new_node_material(name):
    """A new material with an empty node tree."""
    return _emptied(bpy.data.materials.new(name))


def new_node_world(name):
    """A new world with an empty node tree."""
    return _emptied(bpy.data.worlds.new(name))


def eevee_engine_id() -> str:
    """EEVEE's render engine id: BLENDER_EEVEE_NEXT in 4.2-4.5, BLENDER_EEVEE from 5.0 on."""
    ids = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in ids else "BLENDER_EEVEE"
