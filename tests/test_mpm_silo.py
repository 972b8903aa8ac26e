"""The 2D silo as pure MPM (tools/mpm_silo.py: mpm_solver with a floor of two obstacle boxes and an
[[outlet]] under the orifice), the continuum calibrated from the silo's grains."""
from __future__ import annotations

import numpy as np
import pytest

from mpm_results import load_run
from mpm_silo import MpmSilo, run

D = 0.002


@pytest.mark.parametrize("model", ["drucker_prager", "mu_i"])
def test_pure_mpm_silo_discharges_and_keeps_its_mass(tmp_path, mpm_solver, model):
    """A reduced silo (W = 30 d, H = 60 d, D = 10 d, cells of 2 d): it discharges (a few per cent
    of the fill in 0.3 s), what is in the run plus what the outlet took is the fill's mass to
    round-off, and the outflow record grows and ends at the summary's outflow. How its rate
    compares with the DEM's, and with the cell, is bench/results/mpm_silo.md's."""
    silo = MpmSilo(width=30 * D, height=60 * D, orifice=10 * D, d=D, model=model, tdis=0.3)
    res = run(silo, tmp_path, threads=1, timeout=600)
    print({k: res[k] for k in ("rate", "rate_first", "rate_second", "discharged_fraction", "steps", "wall_time")})
    frames = load_run(tmp_path)
    first, last = frames.frame(0), frames.frame(-1)
    mass0 = np.sum(first["mass"])
    assert mass0 == pytest.approx(silo.mass0(), rel=1e-9)
    assert np.sum(last["mass"]) + res["outflow_mass"] == pytest.approx(mass0, rel=1e-12)
    record = np.loadtxt(tmp_path / "outflow.dat", ndmin=2)
    assert record[-1, 1] == pytest.approx(res["outflow_mass"], rel=1e-9)
    assert np.all(np.diff(record[:, 1]) >= 0) and record[-1, 2] == len(first["mass"]) - len(last["mass"])
    assert 0.02 < res["discharged_fraction"] < 0.5 and res["rate"] > 0
