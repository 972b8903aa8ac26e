"""bench/silo_flow_field.py: the map of where the mass sits, over the packing's mass per area.

The bench itself is not a test (it runs a DEM and a hybrid silo); its map is read as "1 is the
packing", so a uniformly packed silo must read 1 in every cell, and mass must land in the cell of
its height and distance from the axis (both sides together).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import silo_flow_field as sff  # noqa: E402

WIDTH = sff.SIZE["width"]


def test_a_uniformly_packed_silo_reads_one_everywhere():
    # bodies at the centres of a fine lattice over the whole width and above the map's top,
    # each carrying the packing's mass per area times its lattice cell's area
    density, h = 2050.0, sff.ROW / 4
    xs, ys = np.meshgrid(np.arange(h / 2, WIDTH, h), np.arange(h / 2, sff.FILL_TOP + 3 * sff.FILL_ROW, h))
    state = dict(x=xs.ravel(), y=ys.ravel(), m=np.full(xs.size, density * h * h))
    fill = np.array(sff.fill_map([state, state], density))
    assert fill.shape == (round(sff.FILL_TOP / sff.FILL_ROW), round(WIDTH / 2 / sff.ROW))
    np.testing.assert_allclose(fill, 1.0, rtol=1e-9)


def test_mass_lands_in_its_row_and_its_distance_from_the_axis():
    # one body 2.2 rows up and 3.4 columns left of the axis; another above the map (left out)
    x = WIDTH / 2 - 3.4 * sff.ROW
    state = dict(x=np.array([x, WIDTH / 2]), y=np.array([2.2 * sff.FILL_ROW, sff.FILL_TOP + sff.FILL_ROW]),
                 m=np.array([1.0, 5.0]))
    fill = np.array(sff.fill_map([state], 1.0))
    expected = np.zeros_like(fill)
    expected[2, 3] = 1.0 / (2 * sff.FILL_ROW * sff.ROW)    # the two mirrored columns' area
    np.testing.assert_allclose(fill, expected, rtol=1e-12, atol=0)
