"""The viewport's heatmaps: a bake's estimated error (`_prt_error`), the last validation's difference from Cycles
(`_prt_validation_error`) or the rule that decided each point (`_prt_rule`, in core.heatmap's colours per rule) as
colours, written into the display colour attribute as the shaded colours are
(display.write_colour_rows), per vertex or per face corner as stored. One scale for every mesh shown
(core.heatmap), so colours compare across objects; a mesh without the values (not validated) is grey.
"""

from dataclasses import dataclass

import numpy as np

from ..core import heatmap, rules
from . import display, storage

SHADED = "SHADED"  # the display mode that shows the PRT colours rather than a heatmap
ATTRIBUTES = {"ERROR": storage.ERROR_ATTRIBUTE, "DIFFERENCE": storage.VALIDATION_ERROR_ATTRIBUTE,
              "RULE": storage.RULE_ATTRIBUTE}
RULE = "RULE"  # categorical: a colour per rule, no scale


@dataclass(frozen=True)
class Legend:
    """What the panel's legend shows: the mode painted, the top of its scale (0 for RULE), the objects without
    values, and for RULE the points each rule decided over every mesh shown (core.rules.counts)."""
    mode: str
    top: float
    missing: tuple
    decided: tuple = ()  # ((key, points), ...)


def read(objects, mode) -> dict:
    """Object name → (values, domain) of the mode's attribute, or None where its mesh does not have it."""
    return {ob.name_full: storage.read_values(ob.data, ATTRIBUTES[mode]) for ob in objects}


def legend(found: dict, mode: str) -> Legend:
    """The one scale for every mesh's values (core.heatmap.scale_top), and which objects have none."""
    values = [rows for rows, _ in filter(None, found.values())]
    missing = tuple(sorted(name for name, rows in found.items() if rows is None))
    if mode == RULE:
        every = np.concatenate(values) if values else np.zeros(0, dtype=np.int32)
        return Legend(mode, 0.0, missing, tuple(rules.counts(every).items()))
    top = heatmap.scale_top(np.concatenate(values) if values else np.zeros(0))
    return Legend(mode, top, missing)


def paint(mesh, found, legend_shown: Legend):
    """One float32 write of the heatmap colours of `found` ((values, domain), or None: grey per vertex)."""
    if found is None:
        display.write_colour_rows(mesh, heatmap.missing_rgba(len(mesh.vertices)), "POINT")
    else:
        values, domain = found
        rgba = (heatmap.rule_rgba(values) if legend_shown.mode == RULE else
                heatmap.heatmap_rgba(values, legend_shown.top))
        display.write_colour_rows(mesh, rgba, domain)
