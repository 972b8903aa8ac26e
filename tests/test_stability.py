"""The stability suite (tools/stability_suite.py, issue 5) at its test size: stiff cases
(Young's modulus and normal stiffness x100) and extreme ones (impacts at 50-60 m/s, a dilute
splash and back, a near-empty cell, shear at 1000/s), each of which must either run stable
(finite, mass exact, energy bounded, momentum exact where nothing external acts) or stop with
a clear error naming the safe step before it goes unstable. About 10 s in all."""
from __future__ import annotations

import os

import pytest

from conftest import BUILD


@pytest.fixture(scope="module")
def suite(tmp_path_factory, hybrid_programs):
    os.environ.setdefault("HYBRID_BUILD_DIR", str(BUILD))
    os.environ["OMP_NUM_THREADS"] = "1"
    from stability_suite import run_suite
    out = tmp_path_factory.mktemp("stability")
    outcomes = {o.name: o for o in run_suite(out, np_=2, progress=False, timeout=300)}
    print((out / "stability.md").read_text())
    return outcomes


CASES = ["stiff_continuum", "stiff_continuum_fixed_dt", "impact_continuum", "impact_fixed_dt", "dilute_and_back",
         "near_empty_cell", "high_shear", "free_collision", "stiff_grains_deck_step", "stiff_grains_safe_step",
         "impact_grains"]


@pytest.mark.parametrize("name", CASES)
def test_case_is_stable_or_stops_with_a_clear_error(suite, name):
    o = suite[name]
    assert o.status == o.expected, f"{name}: {o.status} ({o.detail})"


def test_refusals_name_the_safe_step(suite):
    assert "Use timestep" in suite["stiff_grains_deck_step"].detail
    for name in ("stiff_continuum_fixed_dt", "impact_fixed_dt"):
        assert "is above the stable step" in suite[name].detail and "set [time] dt <=" in suite[name].detail
    # the impact's fixed step is refused during the run, once the speed makes it unstable
    assert "at t = 0 s" not in suite["impact_fixed_dt"].detail


def test_the_named_safe_step_runs_the_stiff_grains_stably(suite):
    for name in ("stiff_grains_safe_step", "impact_grains"):
        o = suite[name]
        assert o.figures["mass_drift"] < 1e-12 and o.figures["energy_rise"] <= 0.05, o.detail


def test_free_collision_keeps_momentum_to_round_off(suite):
    assert suite["free_collision"].figures["momentum_drift"] < 1e-10
