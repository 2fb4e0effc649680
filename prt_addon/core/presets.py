"""The bake presets, defined once: Draft, Production and Final. The sidebar's preset menu (its bundled preset files
call an operator that reads them here) and `prt bake --preset NAME` both apply exactly these values; explicit
command-line options and later edits in the panel override them."""

from dataclasses import dataclass

from . import settings as spec

# Each preset sets every setting that decides what and how accurately the bake computes; the seed, the bounce
# tolerance and the workers stay as they are (workers only change how fast, and depend on the machine).
FIELDS = (spec.MODE, spec.ORDER, spec.SAMPLES, spec.TARGET_ERROR, spec.MAX_SAMPLES, spec.BOUNCES)


@dataclass(frozen=True)
class Preset:
    description: str
    values: dict  # {setting name: value}; None for bounces means auto


PRESETS = {
    "draft": Preset("Shadows to judge the lighting by: order 3, 64 rays per vertex (est. error about 3 % on the "
                    "demo scene)",
                    {"mode": "shadowed", "order": 3, "samples": 64, "target_error": 0.0, "max_samples": 16384,
                     "bounces": None}),
    "production": Preset("Order 4, each vertex sampled until its estimated error is below 1 %",
                         {"mode": "shadowed", "order": 4, "samples": 256, "target_error": 0.01, "max_samples": 4096,
                          "bounces": None}),
    "final": Preset("Bounced light at order 6, each vertex sampled until its estimated error is below 0.5 %",
                    {"mode": "interreflected", "order": 6, "samples": 512, "target_error": 0.005,
                     "max_samples": 16384, "bounces": None}),
}


def preset_values(name: str) -> dict:
    """The settings of preset `name` (any case)."""
    return dict(PRESETS[name.lower()].values)


def label(name: str) -> str:
    return name.capitalize()
