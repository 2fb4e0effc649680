"""The reference pages' writers, one module per page (docs/gen_reference.py runs them): each reads what it documents
from the add-on's own definitions, so a page cannot say what the code does not do."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
