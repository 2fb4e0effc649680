"""The viewport's heatmaps: a bake's estimated error (`_prt_error`) or the last validation's difference from Cycles
(`_prt_validation_error`) as colours, written into the display colour attribute as the shaded colours are
(display.write_colour_rows), per vertex or per face corner as stored. One scale for every mesh shown
(core.heatmap), so colours compare across objects; a mesh without the values (not validated) is grey.
"""

from dataclasses import dataclass

import numpy as np

from ..core import heatmap
from . import display, storage

SHADED = "SHADED"  # the display mode that shows the PRT colours rather than a heatmap
ATTRIBUTES = {"ERROR": storage.ERROR_ATTRIBUTE, "DIFFERENCE": storage.VALIDATION_ERROR_ATTRIBUTE}


@dataclass(frozen=True)
class Legend:
    """What the panel's legend shows: the mode painted, the top of its scale, the objects without values."""
    mode: str
    top: float
    missing: tuple


def read(objects, mode) -> dict:
    """Object name → (values, domain) of the mode's attribute, or None where its mesh does not have it."""
    return {ob.name_full: storage.read_values(ob.data, ATTRIBUTES[mode]) for ob in objects}


def legend(found: dict, mode: str) -> Legend:
    """The one scale for every mesh's values (core.heatmap.scale_top), and which objects have none."""
    values = [rows for rows, _ in filter(None, found.values())]
    top = heatmap.scale_top(np.concatenate(values) if values else np.zeros(0))
    return Legend(mode, top, tuple(sorted(name for name, rows in found.items() if rows is None)))


def paint(mesh, found, top: float):
    """One float32 write of the heatmap colours of `found` ((values, domain), or None: grey per vertex)."""
    if found is None:
        display.write_colour_rows(mesh, heatmap.missing_rgba(len(mesh.vertices)), "POINT")
    else:
        values, domain = found
        display.write_colour_rows(mesh, heatmap.heatmap_rgba(values, top), domain)
