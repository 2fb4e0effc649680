"""Materials and worlds for tests, built node by node: what a new material or world holds (a tree or none, a
Principled BSDF or nothing) differs between Blender versions, so no test relies on it."""

from prt_addon.blender.compat import new_node_material, new_node_world


def principled_material(name, base_colour=(0.8, 0.8, 0.8), texture=None, **inputs):
    """A Principled BSDF into the Material Output; `texture` (an image) feeds its Base Color; `inputs` set other
    sockets by name, e.g. principled_material("Wax", **{"Subsurface Weight": 1.0})."""
    material = new_node_material(name)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    principled = nodes.new("ShaderNodeBsdfPrincipled")
    links.new(principled.outputs["BSDF"], nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    principled.inputs["Base Color"].default_value = (*base_colour, 1.0)
    for socket, value in inputs.items():
        principled.inputs[socket].default_value = value
    if texture is not None:
        node = nodes.new("ShaderNodeTexImage")
        node.image = texture
        links.new(node.outputs["Color"], principled.inputs["Base Color"])
    return material


def environment_world(name):
    """(world, its Environment Texture node): the texture into a Background into the World Output."""
    world = new_node_world(name)
    nodes, links = world.node_tree.nodes, world.node_tree.links
    texture = nodes.new("ShaderNodeTexEnvironment")
    background = nodes.new("ShaderNodeBackground")
    links.new(texture.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], nodes.new("ShaderNodeOutputWorld").inputs["Surface"])
    return world, texture
