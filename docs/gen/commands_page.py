"""docs/reference/commands.md: every `prt` command, its usage and each option's value, default and help, read from
the parser the command line itself builds (prt_addon.commands.cli.build_parser). The usage lines are composed here
rather than by argparse, whose layout differs between the Pythons the supported Blenders run."""

import argparse

from prt_addon.commands import cli as commands_cli
from prt_addon.core import settings as spec

from . import cli
from .markdown import code, page, table, value

SETTINGS = {item.name: item for item in vars(spec).values() if isinstance(item, spec.Setting)}
INTRO = f"""\
One parser serves three ways of running a command; they take the same options and behave the same:

```sh
prt COMMAND [OPTIONS]                                      # the command setup.sh installs into .venv
python -m prt_addon COMMAND [OPTIONS]                      # the same, with the venv's Python
blender --background FILE.blend --command prt COMMAND [OPTIONS]   # a real Blender with the extension enabled
```

`prt` and `python -m prt_addon` run with the bpy module setup.sh installs (`.venv/bin/prt`, or `prt` once the venv
is activated with `. .venv/bin/activate`). In a real Blender a command works on the file Blender opened, so its
`FILE` argument may be left out. `prt --help` and `prt COMMAND --help` print what this page shows.

Every command ends with exit code 0 on success, or 1 and one line saying what was wrong
(`prt: error: ...`), before any work where the input is at fault. Ctrl+C stops a command with exit code 1 and
SIGTERM (a farm or service manager stopping it) with {commands_cli.TERMINATED_EXIT_CODE}; either way nothing
half-written is left, the input file is as it was and temporary folders are removed. Outputs never replace an
input and are written whole or not at all.
"""


def text() -> str:
    parsers = cli.commands()
    helps = cli.help_lines(commands_cli.build_parser())
    summary = table(["Command", "What it does"], [(f"[`{name}`](#prt-{name})", helps[name]) for name in parsers])
    return page("Commands", INTRO, "## The commands\n\n" + summary,
                *(_command(name, parser, helps[name]) for name, parser in parsers.items()))


def _command(name: str, parser: argparse.ArgumentParser, summary: str) -> str:
    parts = [f"## prt {name}\n\n{summary[0].upper()}{summary[1:]}.\n",
             "```text\n" + _usage(parser) + "\n```\n"]
    # argparse's own groups (the arguments, the options) as one table, then each group the command names
    groups = [[parser._positionals, parser._optionals]] + [
        [group] for group in parser._action_groups if group not in (parser._positionals, parser._optionals)]
    for members in groups:
        actions = [action for group in members for action in group._group_actions
                   if not isinstance(action, argparse._HelpAction)]
        if not actions:
            continue
        group = members[0]
        if group is not parser._positionals:
            about = f"\n\n{group.description[0].upper()}{group.description[1:]}." if group.description else ""
            parts.append(f"**{group.title[0].upper()}{group.title[1:]}**{about}\n")
        parts.append(table(["Option", "Value", "Default", "What it does"],
                           [(code(_flags(action)), _value(action), _default(action), action.help or "—")
                            for action in actions]))
    return "\n".join(parts)


def _flags(action: argparse.Action) -> str:
    return cli.flags(action) if action.option_strings else _metavar(action)


def _metavar(action: argparse.Action) -> str:
    if action.choices:
        return "{" + ",".join(str(choice) for choice in action.choices) + "}"
    return action.metavar or action.dest.upper()


def _usage(parser: argparse.ArgumentParser) -> str:
    """`prt NAME` and each argument as argparse's usage writes it, an optional one in brackets, wrapped at 100."""
    words = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        if not action.option_strings:
            word = action.metavar or action.dest.upper()
            nargs = {"?": "[{}]", "*": "[{} ...]", "+": "{} [{} ...]"}.get(action.nargs, "{}")
            words.append(nargs.format(word, word))
            continue
        if action.nargs == 0:
            word = " | ".join(action.option_strings)
        else:
            word = f"{action.option_strings[0]} {_metavar(action)}"
        words.append(word if action.required else f"[{word}]")
    lines, line = [], parser.prog
    for word in words:
        if len(line) + 1 + len(word) > 100:
            lines.append(line)
            line = " " * (len(parser.prog) + 1) + word
        else:
            line += " " + word
    return "\n".join(lines + [line])


def _value(action: argparse.Action) -> str:
    if action.nargs == 0 or not action.option_strings:
        return "—"
    if action.choices:
        return "one of " + ", ".join(code(choice) for choice in action.choices)
    return code(action.metavar or action.dest.upper())


def _default(action: argparse.Action) -> str:
    default = action.default
    if default is argparse.SUPPRESS:  # a setting's option: left out unless given, so a preset's value can stand
        setting = SETTINGS.get(action.dest)
        return "—" if setting is None else "`auto`" if setting.auto else value(setting.default)
    if default is None or (action.nargs == 0 and default is False):
        return "—"
    if isinstance(default, tuple) and all(isinstance(item, int) for item in default):
        return code("x".join(str(item) for item in default))  # a resolution, WxH as it is typed
    return value(default)
