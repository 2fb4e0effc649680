"""Extension entry point: Blender imports this; everything lives in the prt_addon package."""

from .prt_addon import register, unregister  # noqa: F401
