"""The maths in numpy, never bpy: SH, rotation, lobes, sampling, the transfer estimator and its job, flat occluders,
interreflection, subsurface scattering, SH lights, shading, settings, statistics, progress and errors. Its one
dependency beyond numpy is mathutils' BVHTree, the ray caster."""
