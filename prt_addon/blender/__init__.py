"""The Blender data layer: between Blender's data and the core's arrays. Geometry and occluders in, albedo from
materials, the stored layout, SH lights from the scene's settings, the relighting engine, the display, the scene
bake, Cycles as a reference and the sample scenes. Nothing here draws or registers interface."""
