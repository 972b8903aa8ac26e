"""Every 3D scene's LAMMPS deck and its LIGGGHTS twin share one parameter block, word for word
(input_decks/<scene>/dem_3d.lmp and liggghts_3d.in, between the "shared parameter block" rule
and the next rule line): the two codes run the same scene only if their parameters cannot drift
apart. The runs themselves are compared in each scene's test."""
from __future__ import annotations

import re

import pytest

from conftest import REPO

SCENES = ["column_collapse", "silo", "plough", "impact"]
BLOCK = re.compile(r"^# -+ shared parameter block.*?\n(.*?)^# -{20,}\s*$", re.M | re.S)


def shared_block(path) -> str:
    m = BLOCK.search(path.read_text())
    assert m, f"{path}: no shared parameter block"
    return m.group(1)


@pytest.mark.parametrize("scene", SCENES)
def test_twin_decks_share_the_parameter_block(scene):
    lammps = shared_block(REPO / "input_decks" / scene / "dem_3d.lmp")
    liggghts = shared_block(REPO / "input_decks" / scene / "liggghts_3d.in")
    assert lammps == liggghts
    # it sets the scene's parameters (at least the grain size, density, friction, restitution)
    for name in ("d", "rho", "mu", "e"):
        assert re.search(rf"^variable\s+{name}\s+index\s", lammps, re.M), (scene, name)


@pytest.mark.parametrize("scene", SCENES)
def test_each_scene_has_its_hybrid_form(scene):
    deck = (REPO / "input_decks" / scene / "hybrid_3d.lmp").read_text()
    assert re.search(r"^fix\s+couple\s+grains\s+hybrid/mpm\s", deck, re.M)
    assert "hybrid_3d.lmp" in (REPO / "input_decks" / scene / "dem_3d.lmp").read_text()
