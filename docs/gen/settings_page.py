"""docs/reference/settings.md: every setting PRT saves in a .blend file, with the panel that shows it, its
command-line option, range, default and description, read from the properties themselves (blender.schema, built
from core.settings for the bake's settings), the panels' drawing code (panels) and the parsers (cli)."""

import math

from prt_addon.blender import schema
from prt_addon.core import presets, settings as spec
from prt_addon.core.errors import InputError

from . import cli, panels
from .markdown import code, page, table, value

# Saved properties no panel draws with a `prop` call, and where a user meets them instead.
NOT_DRAWN = {
    (panels.OBJECT, "prt_probe_volume"): "**Add Probe Volume** (PRT › Bake) makes an Empty with it on",
    ("prt_lights", "use"): "the checkbox beside each light in the PRT › Lights list",
    ("prt_lights", "sun_lamp"): "made by **Split Off Sun**",
}
SETTINGS = spec.BAKE + spec.TEXEL + (spec.WORKERS, spec.ORDER_TARGET, spec.DYNAMIC, spec.PROBE_LIGHT,
                                     spec.PROBE_VOLUME, spec.PROBE_RESOLUTION)
POINTERS = {"Object": "an object", "Image": "an image"}
INTRO = """\
The settings PRT saves with a `.blend` file: the scene's bake settings, each object's storage, the SH lights, the
display and the validation. Each bake setting is defined once (`prt_addon/core/settings.py`): the sidebar's
properties, the options of `prt bake` and their range checks all read that definition, so the panel, the command
line and this page agree. A value out of range is refused as it is typed or read, with its range
(`prt bake --target-error 5`: `{refusal}`).

In Python the settings are properties of the scene and of each object: `bpy.context.scene.prt_bake.order = 6`,
`bpy.data.objects["Floor"].prt_storage = "texel"`. A setting of `prt bake` applies to every object the bake
receives; without the option each object keeps its own.
"""


def text() -> str:
    parsers = cli.commands()
    try:
        parsers["bake"].parse_args(["--target-error", "5"])
    except InputError as refused:  # what the command line says, after its "prt bake: argument --target-error: "
        refusal = str(refused).rsplit(": ", 1)[-1]
    drawn = panels.drawn()
    parts = [INTRO.format(refusal=refusal),
             "## Bake\n\nThe scene's bake settings (`scene.prt_bake`).\n",
             _group(schema.PRT_PG_bake_settings.__annotations__, "prt_bake", "scene.prt_bake.", drawn,
                    parsers["bake"], "prt bake"),
             _presets(),
             "## Each object\n\nWhere each object's transfer is stored, whether it moves, and probe volumes. "
             "`prt bake`'s options set them on every object it bakes.\n",
             _group({name: prop for _, name, prop in schema.OBJECT_STORAGE}, panels.OBJECT, "object.", drawn,
                    parsers["bake"], "prt bake"),
             "## SH lights\n\nEach SH light of the scene (`scene.prt_lights`, the active one "
             "`scene.prt_active_light`). `prt bake` and `prt relight` add lights with `--sun`, `--env` and `--sky` "
             "([commands](commands.md)).\n",
             _group(schema.PRT_PG_light.__annotations__, "prt_lights", "scene.prt_lights[i].", drawn),
             "## Display\n\nHow the viewport shows the bake (`scene.prt_display`).\n",
             _group(schema.PRT_PG_display.__annotations__, "prt_display", "scene.prt_display.", drawn),
             "## Validation\n\nThe comparison with Cycles (`scene.prt_validate`).\n",
             _group(schema.PRT_PG_validate_settings.__annotations__, "prt_validate", "scene.prt_validate.", drawn,
                    parsers["validate"], "prt validate")]
    return page("Settings", *parts)


def _group(properties: dict, owner: str, python: str, drawn: dict, parser=None, command: str = "") -> str:
    """A table of one property group, then the choices of each of its choice properties."""
    headers = ["Setting", "Panel"] + ([f"`{command}`"] if parser else []) + ["Range", "Default", "What it does",
                                                                             "Python"]
    rows, choices = [], []
    for name, prop in properties.items():
        keywords = prop.keywords
        where = drawn.get((owner, name)) or NOT_DRAWN.get((owner, name))
        if where is None:
            raise ValueError(f"no panel draws {owner}.{name}: say where users set it in NOT_DRAWN")
        if (owner, name) in drawn and (owner, name) in NOT_DRAWN:
            raise ValueError(f"{owner}.{name} is drawn by {drawn[(owner, name)]}: take it out of NOT_DRAWN")
        setting = next((setting for setting in SETTINGS if (setting.label, setting.description) ==
                        (keywords.get("name"), keywords.get("description"))), None)  # the one it is made from
        flag = [code(option) if (option := cli.option_for(parser, name.removeprefix("prt_"))) != "—" else "—"] \
            if parser else []
        rows.append([keywords.get("name", name), where, *flag, _range(prop, setting), _default(prop, setting),
                     keywords.get("description", "—"), code(python + name)])
        if "items" in keywords:
            choices.append(_choices(keywords["name"], keywords["items"]))
    return table(headers, rows) + "".join("\n" + part for part in choices)


def _choices(label: str, items) -> str:
    return f"**{label}**:\n\n" + table(["Value", "In the panel", "Meaning"],
                                       [(code(item[0]), item[1], item[2]) for item in items])


def _angle(prop) -> bool:
    return prop.keywords.get("subtype") in ("ANGLE", "EULER")


def _range(prop, setting) -> str:
    if setting is not None and not setting.choices and not isinstance(setting.default, bool):
        return setting.range_text() + (" or `auto`" if setting.auto else "")
    kind, keywords = prop.function.__name__, prop.keywords
    if "items" in keywords:
        return "one of " + ", ".join(code(item[0]) for item in keywords["items"])
    if kind == "BoolProperty":
        return "on or off"
    if kind == "StringProperty":
        return "a name"
    if kind == "PointerProperty":
        return POINTERS[keywords["type"].__name__]
    if kind == "CollectionProperty":
        return "a list"
    unit = "°" if _angle(prop) else ""
    low, high = (_number(keywords[key], prop) + unit if key in keywords else None for key in ("min", "max"))
    size = f"{keywords['size']} {'angles' if unit else 'numbers'}" if "size" in keywords else ""
    if low is not None and high is not None:
        return f"{size}{', each ' if size else ''}{low}-{high}"
    if low is not None:
        return f"{size}{', each ' if size else ''}at least {low}"
    return size or "any"


def _default(prop, setting) -> str:
    if setting is not None:
        return value(setting.default) + (" (Auto Bounces on)" if setting.auto else "")
    kind, keywords = prop.function.__name__, prop.keywords
    if "default" not in keywords:
        if "size" in keywords:
            return ", ".join(["0°" if _angle(prop) else "0"] * keywords["size"])
        if "items" in keywords:
            return value(keywords["items"][0][0])
        return {"BoolProperty": "off", "StringProperty": "(empty)", "PointerProperty": "none",
                "CollectionProperty": "empty"}.get(kind, "0")
    shown = keywords["default"]
    if _angle(prop):
        degrees = [_number(angle, prop) + "°" for angle in (shown if isinstance(shown, tuple) else (shown,))]
        return ", ".join(degrees)
    return value(shown)


def _number(number, prop) -> str:
    return f"{math.degrees(number):.4g}" if _angle(prop) else value(number)


def _presets() -> str:
    """The presets' values, a column per setting they set."""
    headers = ["Preset"] + [setting.label for setting in presets.FIELDS] + ["What it is for"]
    rows = [[presets.label(name)] + [("auto" if value_ is None else value(value_))
                                      for value_ in (preset.values[setting.name] for setting in presets.FIELDS)]
            + [preset.description] for name, preset in presets.PRESETS.items()]
    return ("### Presets\n\nThe preset menu at the top of the Bake panel and `prt bake --preset NAME` set exactly "
            "these; options given with `--preset` override them, and the seed, the tolerance and the workers stay "
            "as they are.\n\n" + table(headers, rows))
