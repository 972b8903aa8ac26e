"""The error-versus-run-time report of the column collapse (tools/collapse_report.py, issue 5)
at reduced size: L0 = 0.05 m = 25 d, aspect 2, about 1300 disks, 2 LAMMPS ranks. One call runs
the LAMMPS DEM reference, the reference from another packing (its noise floor), the hybrid
with fixed and with adaptive zones, and pure MPM with both models, and writes the table, the
JSON and the two plots. About 4 minutes (the settled columns are cached across tests).

Measured (this machine): surface error: noise floor 1.4 % of H0 (runout -0.2 %), hybrid fixed
2.4 %, adaptive 7.1 %, MPM mu(I) 3.4 %, Drucker-Prager 6.9 %; kinetic-energy history error (over
the reference's peak): floor 1.6 %, hybrid fixed 3.1 %, adaptive 23.7 %, MPM mu(I) 14.6 %,
Drucker-Prager 18.9 %. A second, low column (a = 0.5) runs a shorter matrix below. The
full-size reports (a = 2 and 0.5, each with its 3D slab section: LAMMPS, LIGGGHTS, the hybrid on each host) are
bench/collapse_report.sh, committed in docs/results/collapse_report*/.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import BUILD

RUNS = ["dem", "dem_seed", "hybrid_fixed", "hybrid_adaptive", "mpm_drucker_prager", "mpm_mu_i"]
WIDTH, ASPECT = 0.05, 2.0
KE_FLOOR = 0.05    # KE history error of the reference from another packing (measured 1.6 %)


@pytest.fixture(scope="module")
def report(tmp_path_factory, hybrid_programs, mpm_solver):
    os.environ.setdefault("HYBRID_BUILD_DIR", str(BUILD))
    os.environ["OMP_NUM_THREADS"] = "1"
    from collapse_report import run_report
    out = tmp_path_factory.mktemp("collapse_report")
    runs, _ = run_report(out, RUNS, aspect=ASPECT, width=WIDTH, np_=2, progress=False)
    print((out / "report.md").read_text())
    return out, {r.name: r for r in runs}


def test_one_command_writes_the_table_the_json_and_the_plots(report):
    out, runs = report
    text = (out / "report.md").read_text()
    rows = [ln for ln in text.splitlines() if ln.startswith("| ") and not ln.startswith("| run ")
            and not ln.startswith("| ---")]
    assert [r.split("|")[1].strip() for r in rows] == [runs[n].label for n in RUNS]
    for png in ("error_vs_time.png", "profiles.png", "kinetic_energy.png"):
        assert (out / png).stat().st_size > 10_000
    data = json.loads((out / "report.json").read_text())
    assert [r["name"] for r in data["runs"]] == RUNS
    # the speedup column is the reference's wall time over each run's
    ref_wall = runs["dem"].wall
    for row, name in zip(rows, RUNS):
        assert float(row.split("|")[-2]) == pytest.approx(ref_wall / runs[name].wall, abs=0.006)


def test_errors_are_those_of_the_saved_surfaces(report):
    """The table's errors, recomputed here from the JSON's surfaces (RMS over 0..farther front, / H0)."""
    out, runs = report
    data = {r["name"]: r for r in json.loads((out / "report.json").read_text())["runs"]}
    xr, hr = (np.asarray(a) for a in data["dem"]["surface"])
    for name in RUNS[1:]:
        x, h = (np.asarray(a) for a in data[name]["surface"])
        grid = np.linspace(0.0, max(x.max(), xr.max()), 400)
        rms = np.sqrt(np.mean((np.interp(grid, x, h, 0, 0) - np.interp(grid, xr, hr, 0, 0)) ** 2))
        assert data[name]["surface_error"] == pytest.approx(rms / (ASPECT * WIDTH), rel=1e-9)
        assert data[name]["runout_error"] == pytest.approx(data[name]["runout"] / data["dem"]["runout"] - 1, rel=1e-9)


def test_reference_noise_floor_is_small(report):
    """Another packing of the same scene: the reference agrees with itself far better than the
    published laws' spread, so errors above the floor are the methods'."""
    _, runs = report
    floor = runs["dem_seed"]
    assert floor.surface_error < 0.05 and abs(floor.runout_error) < 0.10
    for name in RUNS[2:]:
        assert 0 < runs[name].surface_error < 0.25, name


def test_adaptive_hybrid_is_near_the_dem_and_rests_when_it_rests(report):
    """The adaptive hybrid with the fix's defaults against the DEM from the same packing (issue
    14). Measured at this size (2026-11-24): runout -12.1 % against this report's DEM (3.10
    against 3.53; a DEM run that prepares the column in the same process runs out 3.28 instead,
    and single hybrid runs gave -0.1 to -7 % against that), final surface 2.8 % of H0, at rest
    after 1.0-1.1x the DEM's steps; the DEM's noise floor here is 1.4 % (surface) and x1.17
    (steps). On a freshly set-up machine (2026-11-26, the same DEM to the step, 73,934): runout
    +0.1 %, surface 2.3 %, at rest after 1.33x the DEM's steps (98,462, four of the deck's rest
    checks later; the same in three runs: a hybrid run is deterministic on one machine, but the
    code is built for its CPU (-march=native), so another CPU is another realization). Before the
    energy ledger's fixes: runout -39 %, surface 7.1 %, 2.6-5x the DEM's steps. Since the kept
    rests and the support force's energy budget (2026-11-26, same machine, deterministic over two
    runs): runout +3.3 %, surface 2.6 %, at rest after 0.92x (67,802 steps); -8.7 %, 1.00x with the
    kept rests alone, -6.9 %, 1.33x with a prototype of the same rule (another order of
    floating-point operations). The targets (runout within 5 %, at rest within 1.2x) are not met in
    every realization (the six numerics of bench/results/settled_bed.md's table spread from +3.6
    to -13.7 %, 1.00-1.33x).
    The bounds are the measured errors with a margin."""
    _, runs = report
    adaptive, dem = runs["hybrid_adaptive"], runs["dem"]
    assert abs(adaptive.runout_error) < 0.16
    assert adaptive.surface_error < 0.045
    assert int(adaptive.steps) <= 1.45 * int(dem.steps), (adaptive.steps, dem.steps)


def test_kinetic_energy_histories_and_their_errors(report):
    """Every run's kinetic energy against time since the release (grains plus points for the
    hybrid, the points' for pure MPM), and the table's KE history error recomputed from them
    (RMS over the reference's times, a run that ended earlier keeping its last value, over the
    reference's peak). The reference starts at rest, peaks during the collapse and comes to
    rest; another packing follows the same history closely."""
    out, runs = report
    data = {r["name"]: r for r in json.loads((out / "report.json").read_text())["runs"]}
    tr, kr = (np.asarray(a) for a in data["dem"]["kinetic_energy"])
    assert tr[0] == 0 and kr[0] < 1e-3 * kr.max() and kr[-1] < 0.05 * kr.max()
    for name in RUNS[1:]:
        t, k = (np.asarray(a) for a in data[name]["kinetic_energy"])
        assert t[0] == 0 and np.all(np.diff(t) > 0) and k.max() > 0, name
        rms = np.sqrt(np.mean((np.interp(tr, t, k) - kr) ** 2)) / kr.max()
        assert data[name]["kinetic_error"] == pytest.approx(rms, rel=1e-9), name
    assert runs["dem_seed"].kinetic_error < KE_FLOOR


# ---- the second aspect ratio: a low column (a = 0.5), whose top stays partly undisturbed ----
LOW_RUNS = ["dem", "hybrid_fixed", "mpm_mu_i"]
LOW_WIDTH, LOW_ASPECT = 0.1, 0.5


@pytest.fixture(scope="module")
def low_report(tmp_path_factory, hybrid_programs, mpm_solver):
    os.environ.setdefault("HYBRID_BUILD_DIR", str(BUILD))
    os.environ["OMP_NUM_THREADS"] = "1"
    from collapse_report import run_report
    out = tmp_path_factory.mktemp("collapse_report_low")
    runs, _ = run_report(out, LOW_RUNS, aspect=LOW_ASPECT, width=LOW_WIDTH, np_=2, progress=False)
    print((out / "report.md").read_text())
    return {r.name: r for r in runs}


def test_low_column_reference_hybrid_and_mpm(low_report):
    """a = 0.5, L0 = 50 d (about 1300 disks). Measured (1 rank): DEM runout 0.81 (published
    0.60-0.90); hybrid with the fixed block (kept below 0.6 H0, in the static wedge) -4.0 %,
    surface error 2.1 % of H0; MPM mu(I) -13.9 %, 7.3 %. Another packing of the DEM: -0.5 %,
    2.7 %."""
    from column_collapse import published_runout_range
    lo, hi = published_runout_range(LOW_ASPECT)
    dem, hybrid, mpm = (low_report[n] for n in LOW_RUNS)
    assert lo <= dem.runout <= hi
    assert abs(hybrid.runout_error) < 0.10 and hybrid.surface_error < 0.05
    assert "points" in hybrid.size and hybrid.height > 0.9 * LOW_ASPECT   # the top at the wall stays (0.96 H0)
    assert abs(mpm.runout_error) < 0.30 and mpm.surface_error < 0.15


def test_slab_section_shows_each_hybrid_against_its_own_host():
    """The 3D slab section (--liggghts) lists the hybrid on each DEM host, and each hybrid's
    runout error against its own host's pure DEM beside the error against LAMMPS."""
    from types import SimpleNamespace

    from collapse_report import make_report
    from hgtools.runner import CODES
    runout = {"lammps": 2.26, "liggghts": 2.11, "hybrid": 2.10, "hybrid_liggghts": 2.02}
    host = {"lammps": "lammps", "liggghts": "liggghts", "hybrid": "lammps", "hybrid_liggghts": "liggghts"}
    runs = {code: dict(runout=r, runout_error=r / runout["lammps"] - 1, surface_error=0.01, collapse_wall=10.0,
                       collapse_steps=1000, speedup=1.0, grains=2756,
                       host_error=r / runout[host[code]] - 1) for code, r in runout.items()}
    assert set(runs) == set(CODES)
    codes = dict(aspect=2.0, width=0.03, thickness=0.012, difference=0.07, runs=runs)
    ref = SimpleNamespace(label="DEM", runout=3.5, runout_error=0.0, surface_error=0.0, kinetic_error=0.0,
                          height=0.4, size=5000, steps=1, extra={}, wall=1.0)
    section = make_report([ref], 2.0, 0.1, 2, codes).split("## 3D slab")[1]
    row = next(line for line in section.splitlines() if "LIGGGHTS as the DEM host" in line).split("|")
    assert row[3].strip() == "-10.6%" and row[4].strip() == "-4.3%", row
    row = next(line for line in section.splitlines() if "(hybrid_3d.lmp)" in line).split("|")
    assert row[3].strip() == row[4].strip() == "-7.1%", row


def test_touched_hybrids_at_depths_in_grain_diameters():
    """hybrid_touch_<N>d runs the touched hybrid with its continuum N grain diameters below the free
    surface (the front of error against run time over the zones' depth); --hcell reaches every
    hybrid; a misspelt run is refused before anything runs."""
    from collapse_report import D, hybrid_vars, label, run_report
    assert hybrid_vars("hybrid_touch", 2.0, 0.2, None) == {"hybrid": 2, "htouch": 1}
    nine = hybrid_vars("hybrid_touch_9d", 2.0, 0.2, 0.0)
    assert nine == {"hybrid": 2, "htouch": 1, "hdepth": pytest.approx(9 * D), "hcell": 0.0}
    assert hybrid_vars("hybrid_adaptive_d2", 2.0, 0.2, None)["hdepth"] == pytest.approx(0.04)
    assert "depth 12.5 d" in label("hybrid_touch_12.5d")
    with pytest.raises(ValueError, match="hybrid_touch_9"):
        run_report(Path("/nonexistent/never"), ["hybrid_touch_9"], progress=False)
