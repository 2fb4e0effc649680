"""The manual (mkdocs.yml, docs/): its reference pages are what the code gives today (docs/gen_reference.py
--check), it builds strict (a broken link, a missing page or a missing image fails the build), every picture the
README and the pages show exists, and the extension's website is the manual's address."""

import importlib.util
import json
import os
from pathlib import Path
import re
import subprocess
import sys
import tomllib

import pytest

from conftest import ROOT

DOCS = ROOT / "docs"
IMAGE = re.compile(r"!\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)|<img\s[^>]*src=\"([^\"]+)\"")


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]


def site_url() -> str:
    return re.search(r"^site_url:\s*(\S+)\s*$", (ROOT / "mkdocs.yml").read_text(), re.MULTILINE).group(1)


def test_the_reference_pages_are_what_the_code_gives():
    done = subprocess.run([sys.executable, str(DOCS / "gen_reference.py"), "--check"], capture_output=True,
                          text=True, timeout=300, cwd=ROOT)
    assert done.returncode == 0, done.stderr


def test_the_check_names_a_page_that_is_missing_or_says_something_else(tmp_path):
    sys.path.insert(0, str(DOCS))
    try:
        import gen_reference
    finally:
        sys.path.remove(str(DOCS))
    same, other, missing = tmp_path / "same.md", tmp_path / "other.md", tmp_path / "missing.md"
    same.write_text("# Same\n", encoding="utf-8")
    other.write_text("# Before\n", encoding="utf-8")
    assert gen_reference.stale({same: "# Same\n", other: "# After\n", missing: "# New\n"}) == [other, missing]


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None,
                    reason="mkdocs is not installed: setup.sh installs it (requirements-dev.txt)")
def test_the_manual_builds_strict(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file",
                           str(ROOT / "mkdocs.yml"), "--site-dir", str(tmp_path / "site")],
                          capture_output=True, text=True, timeout=300, cwd=ROOT,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "site" / "reference" / "gltf-extras.schema.json").is_file()  # the schema is published
    assert not list((tmp_path / "site").rglob("*.py"))  # the scripts that make the pages are not


def test_every_image_the_readme_and_the_manual_show_exists():
    shown = {(page, target) for page in pages() for match in IMAGE.finditer(page.read_text(encoding="utf-8"))
             for target in match.groups() if target and not re.match(r"[a-z]+:", target)}
    missing = [f"{page.relative_to(ROOT)}: {target}" for page, target in sorted(shown)
               if not (page.parent / target.split("#")[0]).is_file()]
    assert shown  # the scan finds the pictures: the README's and the manual's
    assert not missing, "pictures shown but missing:\n" + "\n".join(missing)


def test_the_extensions_website_is_the_manuals_address():
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert manifest["website"] == site_url()
    assert site_url().startswith("https://") and site_url().endswith("/")


def test_the_gltf_schema_is_a_valid_draft_2020_12_schema():
    jsonschema = pytest.importorskip("jsonschema", reason="setup.sh installs jsonschema (requirements-dev.txt)")
    schema = json.loads((DOCS / "reference" / "gltf-extras.schema.json").read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    assert schema["$id"] == site_url() + "reference/gltf-extras.schema.json"  # where the manual publishes it
