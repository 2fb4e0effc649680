"""register() and unregister() for a module that defines Blender classes (the saved settings' schema, an interface
module): its classes, and the properties they add to Blender's types (attached once the classes exist, removed
before they go)."""

import bpy


def classes_and_properties(classes, properties):
    """`properties`: (type, attribute name, property) triples, such as
    (bpy.types.Scene, "prt_bake", PointerProperty(type=PRT_PG_bake_settings))."""
    register_classes, unregister_classes = bpy.utils.register_classes_factory(classes)

    def register():
        register_classes()
        for owner, name, prop in properties:
            setattr(owner, name, prop)

    def unregister():
        for owner, name, _ in reversed(properties):
            delattr(owner, name)
        unregister_classes()

    return register, unregister
