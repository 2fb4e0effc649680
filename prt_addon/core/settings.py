"""The bake's settings, defined once: name, label, description, default and range of each. The sidebar's
properties, the command line's options and help text, `BakeSettings`' defaults and its range checks all read them
from here, so they cannot disagree."""

from dataclasses import dataclass
import os

MAX_ORDER = 16
FEWEST_SAMPLES = 8
MOST_SAMPLES = 1 << 20
MAX_WORKERS = 64
MAX_SEED = (1 << 31) - 1  # the largest a Blender IntProperty holds, so panel and command line agree


@dataclass(frozen=True)
class Setting:
    name: str             # BakeSettings field and property name; the command-line option is --name-with-dashes
    label: str
    description: str
    default: object
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple = ()   # (identifier, label, description) for a choice of one
    auto: bool = False    # also takes "auto" (None in BakeSettings, the default); `default` is the manual value

    def range_text(self) -> str:
        if self.choices:
            return "one of " + ", ".join(identifier for identifier, _, _ in self.choices)
        low, high = (f"{limit:g}" if isinstance(limit, float) else str(limit) for limit in (self.minimum, self.maximum))
        return f"{low}-{high}" if self.maximum is not None else f"at least {low}"

    def contains(self, value) -> bool:
        if self.auto and value is None:
            return True
        if self.choices:
            return value in {identifier for identifier, _, _ in self.choices}
        return ((self.minimum is None or value >= self.minimum) and (self.maximum is None or value <= self.maximum)
                and value == value)  # NaN is in no range


MODE = Setting("mode", "Mode", "What the transfer holds", "shadowed", choices=(
    ("unshadowed", "Unshadowed", "Cosine term only: exact, instant, no rays"),
    ("shadowed", "Shadowed", "Cosine term and visibility from ray casts: soft shadows"),
    ("interreflected", "Interreflected",
     "Shadows plus light bounced between surfaces, coloured by their albedo (no extra rays)"),
))
ORDER = Setting("order", "Order", "SH bands (order n stores n² coefficients)", 4, 1, MAX_ORDER)
SAMPLES = Setting("samples", "Samples", "Rays per vertex (the first round when a target error is set)", 256,
                  FEWEST_SAMPLES, MOST_SAMPLES)
TARGET_ERROR = Setting("target_error", "Target Error",
                       "Keep sampling each vertex until its estimated relative error is below this (0: off)",
                       0.0, 0.0, 1.0)
MAX_SAMPLES = Setting("max_samples", "Max Samples", "Ray budget per vertex when a target error is set",
                      16384, FEWEST_SAMPLES, MOST_SAMPLES)
SEED = Setting("seed", "Seed", "Random seed: the same seed gives the same bake", 0, 0,
               MAX_SEED)
BOUNCES = Setting("bounces", "Bounces", "Interreflection bounces; auto: until the rest of the series is below the "
                  "tolerance", 2, 0, 1000, auto=True)
BOUNCE_TOLERANCE = Setting("bounce_tolerance", "Tolerance", "Relative error that auto bounces may leave out",
                           1e-3, 1e-8, 0.5)
ORDER_TARGET = Setting("order_target", "Target", "Order from lights: the lowest order whose predicted shading error "
                       "under the scene's lights is at most this", 0.03, 0.001, 0.5)
RAY_ENGINE = Setting("ray_engine", "Ray Engine", "What casts the rays (the bakes agree but for float32 rounding)",
                     "auto", choices=(
    ("auto", "Auto", "Embree where it is installed, else Blender's BVHTree"),
    ("embree", "Embree", "Intel's Embree (the embreex package): whole batches of rays in C, many times faster"),
    ("bvhtree", "BVHTree", "Blender's own ray tree, one ray per Python call: everywhere Blender runs"),
))
WORKERS = Setting("workers", "Workers", "Processes that cast rays in parallel (the result is the same); 0: one per "
                  "core of this machine", 0, 0, MAX_WORKERS)

# What BakeSettings holds, in the order the panel and the help show them; workers only change how fast. The ray
# engine is held because a bake's bits follow it (its farm shards must share it), though not what it computes.
BAKE = (MODE, ORDER, SAMPLES, TARGET_ERROR, MAX_SAMPLES, SEED, BOUNCES, BOUNCE_TOLERANCE, RAY_ENGINE)

# Per object: where its transfer is stored (blender.texel_bake). The command line's options apply to every receiver.
STORAGE = Setting("storage", "Storage", "Where the transfer is stored", "vertex", choices=(
    ("vertex", "Vertex", "Per vertex (per face corner where normals split): one dot product per vertex"),
    ("texel", "Texel", "Per texel of a lightmap UV map: shadows and light between vertices"),
    ("auto", "Auto", "Per texel only where interpolating between vertices misses the target error (or 1 %)"),
))
RESOLUTION = Setting("resolution", "Resolution", "Texels along each side of the lightmap; 0: from the texel size, "
                     "else from the target error", 0, 0, 8192)
TEXEL_SIZE = Setting("texel_size", "Texel Size", "Size of one texel on the surface (scene units); 0: from the "
                     "target error", 0.0, 0.0, 1e6)
TEXEL = (STORAGE, RESOLUTION, TEXEL_SIZE)
# Per object: a rigid object that may move and turn after its bake. Its transfer is baked against itself alone, in
# its own frame, and the display turns the SH lights into that frame (blender.request, blender.relighting).
DYNAMIC = Setting("dynamic", "Dynamic", "Bake its self-shadowing in its own frame, against itself only, so it may "
                  "move and turn without a rebake; other objects neither shadow it nor are shadowed by it", False)
# Per object: where a dynamic object takes the probes' light (core.probe_grid, blender.dynamic_shading).
PROBE_LIGHT = Setting("probe_light", "Probe Light", "Where a dynamic object takes the light the probe volume carries",
                      "vertex", choices=(
    ("vertex", "Per Vertex", "Each vertex its own blend of the probes around it: shadows fall across the object"),
    ("centre", "At Centre", "One blend at the centre of its bounding box for the whole object: for objects small "
                            "beside the probe spacing"),
))
# Per object: an Empty whose cube holds a grid of PRT probes (core.probe_transfer, core.probe_grid), baked with the
# static scene; the dynamic objects inside it are lit through them (blender.probe_volumes).
PROBE_VOLUME = Setting("probe_volume", "Probe Volume", "Its cube holds a grid of PRT probes, baked with the static "
                       "scene, that carry the scene's shadows and bounced light to the dynamic objects inside it",
                       False)
PROBE_RESOLUTION = Setting("probe_resolution", "Probes", "Probes along the volume's X, Y and Z, one at the centre of "
                           "each cell", (4, 4, 4), 1, 64)


def worker_count(workers: int) -> int:
    """The processes a Workers setting asks for: 0 means one per core, so a bake uses the machine it runs on."""
    return workers or os.cpu_count() or 1
