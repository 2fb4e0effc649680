"""The command line as its parser builds it (prt_addon.commands.cli): each command's parser, and an option's flags
and dest, read from argparse's own records so that the pages show exactly what `prt` accepts."""

import argparse

from prt_addon.commands.cli import build_parser


def commands() -> dict[str, argparse.ArgumentParser]:
    """{command: its parser}, in the order `prt --help` lists them."""
    parser = build_parser()
    (chooser,) = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
    return dict(chooser.choices)


def help_lines(parser: argparse.ArgumentParser) -> dict[str, str]:
    """{command: its one-line help}, as `prt --help` shows them."""
    (chooser,) = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
    return {choice.dest: choice.help for choice in chooser._choices_actions}


def flags(action: argparse.Action) -> str:
    """The option as typed: `--order`; `--dynamic, --no-dynamic`."""
    return ", ".join(action.option_strings)


def option_for(parser: argparse.ArgumentParser, name: str) -> str:
    """The flags of the option that sets `name` (its dest, or `no_` + it for a switch that turns it off), or an
    em dash where the command line has none."""
    for action in parser._actions:
        if action.option_strings and action.dest in (name, "no_" + name):
            return " / ".join(action.option_strings)
    return "—"
