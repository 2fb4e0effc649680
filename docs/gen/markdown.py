"""Markdown pieces the reference pages share: a page's notice, tables, inline code and values as a user types them."""

import re

NOTICE = ("<!-- Written by docs/gen_reference.py from the add-on's code: change the code or the generator, then run "
          "`.venv/bin/python docs/gen_reference.py`; tests/test_docs.py fails while this page is stale. -->\n")


def cell(text) -> str:
    """One table cell: on one line, its pipes escaped but in code, where the table reads none as a border."""
    parts = re.split(r"(`+[^`]*`+)", " ".join(str(text).split()))
    return "".join(part if part.startswith("`") else part.replace("|", "\\|") for part in parts)


def table(headers, rows) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + " --- |" * len(headers)]
    lines += ["| " + " | ".join(cell(value) for value in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def code(text) -> str:
    """Inline code, with a backtick fence long enough for what it holds."""
    text = str(text)
    fence = "``" if "`" in text else "`"
    padding = " " if text.startswith("`") or text.endswith("`") else ""
    return f"{fence}{padding}{text}{padding}{fence}"


def value(shown) -> str:
    """A default or limit as a user types it: numbers without float noise, tuples as X, Y, Z, text as code."""
    if isinstance(shown, bool):
        return "on" if shown else "off"
    if isinstance(shown, float):
        return f"{shown:g}"
    if isinstance(shown, (tuple, list)):
        return ", ".join(value(item) for item in shown)
    if isinstance(shown, str):
        return code(shown) if shown else "(empty)"
    return str(shown)


def page(title: str, *parts: str) -> str:
    """A whole page: the notice, the title and its parts, separated by blank lines, ending in one newline."""
    return NOTICE + "\n" + f"# {title}\n\n" + "\n".join(part.rstrip("\n") + "\n" for part in parts)
