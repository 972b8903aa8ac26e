"""The calibrated materials the decks use (input_decks/materials/NAME.toml, written by
tools/calibrate.py; docs/calibration.md): one reader for the tools and benches that need their
constants."""
from __future__ import annotations

import tomllib
from pathlib import Path

MATERIALS = Path(__file__).resolve().parents[2] / "input_decks" / "materials"


def material_path(name: str) -> Path:
    """The file of the committed material `name`."""
    return MATERIALS / f"{name}.toml"


def read_material(name: str) -> dict:
    """The whole material file of `name` ([material], [contact], [continuum] tables)."""
    return tomllib.loads(material_path(name).read_text())
