"""Planar column collapse with the pure MPM solver against the published runout
laws (Lube et al. 2005, Lajeunesse et al. 2005; docs/design.md section 6)."""
from __future__ import annotations

import numpy as np
import pytest

from column_collapse import ColumnCollapse, normalised_runout, published_runout_range
from conftest import run_mpm
from mpm_results import load_run

# Friction angle of the continuum: 30 degrees (dry sand / glass beads), floor mu = 0.5.
FRICTION_ANGLE = 30.0
TOLERANCE = 0.25  # the bar: within 25 % of the published law


def collapse(tmp_path, mpm_solver, scene: ColumnCollapse):
    path = scene.write(tmp_path)
    run_mpm(mpm_solver, path)
    run = load_run(str(tmp_path / "output"))
    return run, run.frame(-1)


@pytest.mark.parametrize("aspect, cell", [(0.5, 0.01), (2.0, 0.005)])
def test_drucker_prager_runout_matches_published_law(tmp_path, mpm_solver, aspect, cell):
    scene = ColumnCollapse(aspect=aspect, width=0.1 if aspect > 1 else 0.2, cell_size=cell,
                           friction_angle=FRICTION_ANGLE)
    run, final = collapse(tmp_path, mpm_solver, scene)
    runout = normalised_runout(final["position"], scene.width, scene.cell_size)
    lo, hi = published_runout_range(aspect)
    print(f"a = {aspect}: (Lf - L0)/L0 = {runout:.3f}, published {lo:.2f}..{hi:.2f}")
    assert (1 - TOLERANCE) * lo <= runout <= (1 + TOLERANCE) * hi
    # The pile has come to rest.
    assert np.max(np.linalg.norm(final["velocity"], axis=1)) < 0.05
    # Mass is carried by the points unchanged.
    first = run.frame(0)
    assert np.sum(final["mass"]) == pytest.approx(np.sum(first["mass"]), rel=1e-12)


@pytest.mark.parametrize("model", ["drucker_prager", "mu_i"])
def test_each_model_collapses_without_nan(tmp_path, mpm_solver, model):
    scene = ColumnCollapse(aspect=2.0, width=0.1, cell_size=0.01, model=model, end_time=0.6,
                           output_interval=0.1)
    run, final = collapse(tmp_path, mpm_solver, scene)
    assert len(run.frames) >= 6
    for i in range(len(run.frames)):
        frame = run.frame(i)
        for name in ("position", "velocity", "stress", "volume"):
            assert np.all(np.isfinite(frame[name])), f"{name} not finite at frame {i}"
    # It collapsed: the top came down and the front moved out.
    assert np.max(final["position"][:, 1]) < 0.8 * scene.height
    assert normalised_runout(final["position"], scene.width, scene.cell_size) > 0.5
