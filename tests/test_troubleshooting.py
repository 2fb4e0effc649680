"""docs/troubleshooting.md lists every error and warning the extension prints: each message the code's message
sites can print has its constant text on the page, and each message the page quotes is made of the code's strings.
Only the source is read (ast): nothing is imported or run.

A message site is, in prt_addon/:
- the message argument of a call in MESSAGE_CALLS: an exception raised to the user (`prt: error: ...`, an
  operator's error report), a part file's refusal, the viewport's note printed once;
- the text (third) argument of `Check(level, subject, text)` whose level names ERROR or WARNING (core/checks.py);
- a string assigned, appended or added to a list named in MESSAGE_LISTS (a bake's, validation's or export's notes
  and problems, told as warnings);
- a `{"failed": message}` outcome (commands/farm_dask.py, raised as an error);
- the message of `report({..."WARNING" or "ERROR"...}, message)` (an operator's report) and of `print(...,
  file=sys.stderr)`;
- every string of the functions and constants in MESSAGE_DEFINITIONS: problems in words that another site tells.
Its text is a str, an f-string or their `+` (implicit concatenation is one str); its pieces are the constant text
between the formatted values. A piece is distinctive when, stripped of spaces and punctuation at its ends, it holds
at least two words (runs of non-space holding a letter); the page must hold each distinctive piece, whitespace
normalised. Info and ok findings, progress and summary lines are not messages.

On the page, a message is a line `> `...`` (a blockquoted code span), what it names written `<like this>`; every
distinctive piece between the placeholders must be made of distinctive pieces of the code's strings."""

import ast
from functools import cache
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "prt_addon"
PAGE = ROOT / "docs" / "troubleshooting.md"

# Calls whose argument at this index is a message: exceptions raised to the user, a part file's refusal
# (core/part_file.py's _check), what the viewport's relighting tells once (blender/relighting.py).
MESSAGE_CALLS = {"InputError": 0, "StaleBake": 0, "ArgumentTypeError": 0, "_Refused": 0, "RuntimeError": 0,
                 "PermissionError": 0, "_check": 1, "_report_once": 0}
MESSAGE_LISTS = {"notes", "problems"}
LOUD_LEVELS = {"ERROR", "WARNING"}
# Functions and module constants (file under prt_addon/, name) whose strings are problems or notes in words that
# another message site tells (a bake's notes are its operator's warnings).
MESSAGE_DEFINITIONS = {
    ("core/bake.py", "problems"), ("core/engines/__init__.py", "EMBREE_MISSING"),
    ("core/engines/__init__.py", "AUTO_FALLBACK"), ("core/outputs.py", "unwritable"), ("core/outputs.py", "refusals"),
    ("core/shards.py", "refusals"), ("core/shards.py", "_part_problem"), ("core/shards.py", "_missing_shards"),
    ("core/part_file.py", "_description_header"), ("core/part_file.py", "problem"),
    ("blender/materials.py", "lost_note"), ("blender/aiming.py", "turn"), ("blender/lights.py", "aim_sun"),
    ("ui/drive.py", "_pick"), ("blender/texel_plan.py", "choose"), ("blender/probe_volumes.py", "write"),
}
PLACEHOLDER = re.compile(r"<[^<>]+>")
QUOTED = re.compile(r"^> `+ ?(.*?) ?`+\s*$", re.MULTILINE)


def normalised(text: str) -> str:
    return " ".join(text.split())


def distinctive(piece: str) -> str | None:
    """The piece stripped of spaces and punctuation at its ends, when it holds at least two words."""
    core = normalised(piece).strip(" .,;:'\"()[]")
    return core if sum(bool(re.search("[A-Za-z]", word)) for word in core.split()) >= 2 else None


def text_of(node) -> str | None:
    """The text of a str, an f-string or their `+`, each formatted value a NUL; None for any other node."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(value.value if isinstance(value, ast.Constant) else "\0" for value in node.values)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        left, right = text_of(node.left), text_of(node.right)
        return None if left is None and right is None else (left or "\0") + (right or "\0")
    return None


def _name(node) -> str:
    return node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else ""


def _names_in(node) -> set[str]:
    return {_name(sub) for sub in ast.walk(node) if isinstance(sub, (ast.Name, ast.Attribute))} | {
        sub.value for sub in ast.walk(node) if isinstance(sub, ast.Constant) and isinstance(sub.value, str)}


def _site_texts(node):
    """The message nodes of one node, if it is a message site."""
    if isinstance(node, (ast.Assign, ast.AugAssign)) and any(
            _name(target) in MESSAGE_LISTS for target in getattr(node, "targets", [getattr(node, "target", None)])):
        value = node.value
        return list(value.elts) if isinstance(value, ast.List) else [value.elt] if isinstance(value, ast.ListComp) \
            else []
    if isinstance(node, ast.Dict):  # commands/farm_dask.py: a failed Dask bake's outcome, raised as InputError
        return [value for key, value in zip(node.keys, node.values)
                if isinstance(key, ast.Constant) and key.value == "failed"]
    if not isinstance(node, ast.Call):
        return []
    called, args = _name(node.func), node.args
    if called in MESSAGE_CALLS and len(args) > MESSAGE_CALLS[called]:
        return [args[MESSAGE_CALLS[called]]]
    if called == "Check" and len(args) >= 3 and _names_in(args[0]) & LOUD_LEVELS:
        return [args[2]]
    if called == "append" and isinstance(node.func, ast.Attribute) and _name(node.func.value) in MESSAGE_LISTS:
        return args[:1]
    if called == "report" and len(args) >= 2 and _names_in(args[0]) & LOUD_LEVELS:
        return [args[1]]
    if called == "print" and any(k.arg == "file" and _name(k.value) == "stderr" for k in node.keywords):
        return args[:1]
    return []


def _strings_in(definition) -> list:
    """The outermost strings of a function (its docstring left out) or an assignment."""
    body = [definition.value] if isinstance(definition, ast.Assign) else \
        definition.body[1:] if ast.get_docstring(definition) is not None else definition.body
    found, inner = [], set()
    for statement in body:
        for node in ast.walk(statement):
            if id(node) not in inner and text_of(node) is not None:
                found.append(node)
                inner.update(id(sub) for sub in ast.walk(node))
    return found


@cache
def sources() -> list[tuple[str, ast.Module]]:
    """(path under prt_addon/, syntax tree) of every module, parsed once for both tests."""
    return [(path.relative_to(PACKAGE).as_posix(), ast.parse(path.read_text(encoding="utf-8")))
            for path in sorted(PACKAGE.rglob("*.py"))]


def message_sites() -> list[tuple[str, str]]:
    """(file:line, text (text_of)) of every message site in prt_addon/."""
    sites, seen = [], set()
    for relative, tree in sources():
        nodes = []
        for node in ast.walk(tree):
            nodes += _site_texts(node)
            names = [node.name] if isinstance(node, ast.FunctionDef) else \
                [_name(target) for target in node.targets] if isinstance(node, ast.Assign) else []
            for name in names:
                if (relative, name) in MESSAGE_DEFINITIONS:
                    seen.add((relative, name))
                    nodes += _strings_in(node)
        for node in nodes:
            text = text_of(node)
            if text is not None:
                sites.append((f"prt_addon/{relative}:{node.lineno}", text))
    missing = MESSAGE_DEFINITIONS - seen
    assert not missing, f"MESSAGE_DEFINITIONS names what no longer exists: {sorted(missing)}"
    return sites


def page_messages() -> list[str]:
    """The messages quoted on the page; every blockquote line is one, or empty (a paragraph whose wrapped line
    begins with '>' would be taken for a quote)."""
    text = PAGE.read_text(encoding="utf-8")
    odd = [line for line in text.splitlines() if line.startswith(">") and line != ">" and not QUOTED.match(line)]
    assert not odd, "docs/troubleshooting.md: blockquote lines that quote no message:\n" + "\n".join(odd)
    return QUOTED.findall(text)


def test_every_message_is_on_the_page():
    page = normalised(PAGE.read_text(encoding="utf-8"))
    missing = [f"{where}: {piece!r}" for where, text in message_sites()
               for piece in filter(None, map(distinctive, text.split("\0"))) if piece not in page]
    assert not missing, "docs/troubleshooting.md lacks these messages' text:\n" + "\n".join(missing)


def code_phrases() -> list[str]:
    """The distinctive constant pieces of every string in prt_addon/ but docstrings, longest first: a message may be
    put together from strings kept apart from its site (a scale's wording, a constant's sentence)."""
    found = set()
    for _, tree in sources():
        docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                      if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                      and ast.get_docstring(node) is not None}
        for node in ast.walk(tree):
            text = text_of(node) if isinstance(node, (ast.Constant, ast.JoinedStr)) else None
            if text is not None and id(node) not in docstrings:
                found.update(filter(None, map(distinctive, text.split("\0"))))
    return sorted(found, key=len, reverse=True)


def test_every_message_on_the_page_is_in_the_code():
    """Each distinctive piece of a quoted message is made of the code's strings: what is left once they are taken
    out holds no two words."""
    phrases = code_phrases()
    messages = page_messages()
    assert len(messages) > 150
    stale = []
    for message in messages:
        for piece in filter(None, map(distinctive, PLACEHOLDER.split(message))):
            for phrase in phrases:
                if phrase in piece:
                    piece = piece.replace(phrase, "\0")
            if any(map(distinctive, piece.split("\0"))):
                stale.append(message)
    assert not stale, "docs/troubleshooting.md quotes messages the code no longer prints:\n" + "\n".join(stale)
