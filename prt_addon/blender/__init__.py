"""The Blender data layer: between Blender's data and the core's arrays. The settings a file saves (schema),
geometry and occluders in, albedo from materials, the stored layout, SH lights from the scene's settings, the
relighting engine and its handlers, the display, the scene bake, Cycles as a reference and validation against it,
rendering, the sample scenes, and what differs between Blender versions (compat). Nothing here draws or registers
interface."""
