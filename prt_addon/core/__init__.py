"""The maths in numpy, never bpy: SH, rotation, lobes, sampling, the transfer estimator and its job, flat occluders,
interreflection, subsurface scattering, SH lights, shading, settings, statistics, progress and errors. Rays meet the
occluders through one ray engine (ray_engine, engines/): mathutils' BVHTree by default, the core's one dependency
beyond numpy, imported only by engines/bvhtree.py; the reference engine needs numpy alone."""
