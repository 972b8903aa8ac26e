"""Coupled LAMMPS + MPM launch, phase 1: build, MPMD launch, handshake, failure handling.

Every run has a subprocess timeout, so a hang is a test failure, never a hung suite. Runs use
tools/hybrid_launch.py (or tools/mpirun.sh directly) on input_decks/hybrid/handshake.lmp,
copied into the test's tmp_path so that its processes can be told apart from any others.
"""
from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import BUILD, REPO
from hgtools.runner import BackgroundJob

DECK = REPO / "input_decks" / "hybrid" / "handshake.lmp"
# the wire protocol version both sides were built with (coupler/include/coupler/version.hpp)
PROTOCOL = int(re.search(r"kProtocolVersion = (\d+);",
                         (REPO / "coupler" / "include" / "coupler" / "version.hpp").read_text()).group(1))
LAUNCH = REPO / "tools" / "hybrid_launch.py"
MPIRUN = REPO / "tools" / "mpirun.sh"
# Generous bound for a failure to stop the whole job (the goal is "within seconds").
STOP_WITHIN = 20.0


def env() -> dict:
    e = dict(os.environ, HYBRID_BUILD_DIR=str(BUILD), OMP_NUM_THREADS="1")
    if os.geteuid() == 0:
        e.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return e


def deck_copy(tmp_path: Path, edit=None, extra: str = "") -> Path:
    text = DECK.read_text()
    if edit is not None:
        text = edit(text)
    deck = tmp_path / "deck.lmp"
    deck.write_text(text + extra)
    return deck


def launch(*args: str, timeout: float = 120, cwd: Path | None = None,
           extra_env: dict | None = None) -> tuple[subprocess.CompletedProcess, float]:
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, str(LAUNCH), *args], capture_output=True, text=True, timeout=timeout,
                          env=dict(env(), **(extra_env or {})), cwd=cwd)
    return proc, time.monotonic() - t0


def output(proc) -> str:
    return proc.stdout + proc.stderr


def with_fixed_faces(text: str) -> str:
    """The deck with a fixed y boundary (adaptive zones and the continuum's walls need fixed faces)."""
    out = text.replace("boundary        p f p", "boundary        f f p")
    assert out != text
    return out


def replace_fix_line(text: str, new_args: str) -> str:
    """Replaces the keywords of the fix hybrid/mpm line."""
    out = re.sub(r"^(fix\s+couple\s+all\s+hybrid/mpm)\s.*$", rf"\1 {new_args}", text, flags=re.M)
    assert out != text
    return out


# ------------------------------------------------------------------------------ success
@pytest.mark.parametrize("np_", [1, 2])
def test_lmp_hybrid_handshake_steps_and_clean_finish(tmp_path, hybrid_programs, np_):
    deck = deck_copy(tmp_path)
    log = tmp_path / "log.lammps"
    proc, _ = launch("-np", str(np_), str(deck), "-var", "nsteps", "200", "-var", "every", "10", "-log", str(log))
    text = output(proc)
    assert proc.returncode == 0, text
    assert f"handshake ok with LAMMPS 29 Sep 2021 on {np_} rank(s)" in text
    assert "coupled run finished at LAMMPS step 200 after 20 exchange(s)" in text
    # the MPM side's time ledger: its terms add up to its total (each printed to 3 digits)
    ledger = re.search(r"mpm_solver: wall time (\S+) s: (.*)", text)
    assert ledger, text
    terms = dict((name.strip(), float(t)) for name, t in re.findall(r"([a-zA-Z0-9 ]+?) (\S+?)(?:,|$)", ledger[2]))
    assert set(terms) == {"waiting for the DEM host", "substeps before the agreement", "agreement",
                          "replies and acknowledgement", "G2P", "output", "substeps after the acknowledgement",
                          "rezones", "other"}, ledger[0]
    assert sum(terms.values()) == pytest.approx(float(ledger[1]), rel=0.01, abs=1e-3), ledger[0]
    assert terms["agreement"] > 0 and terms["waiting for the DEM host"] > 0, ledger[0]
    lammps_log = log.read_text()
    assert "fix hybrid/mpm: handshake ok with the MPM process (1 rank(s)): mpm_solver" in lammps_log
    assert re.search(r"mpm_solver \S+ \(pid \d+, 1 OpenMP thread\) ready", lammps_log), lammps_log
    assert f"protocol {PROTOCOL}" in lammps_log and "cell 0.01, model drucker_prager" in lammps_log
    assert "fix hybrid/mpm: finished the coupled run after 20 exchange(s)" in lammps_log
    # f_couple (thermo column) counts the exchanges
    last = [ln.split() for ln in lammps_log.splitlines() if re.match(r"^\s+200\s+630\s", ln)]
    assert last and float(last[-1][-1]) == 20.0, lammps_log


@pytest.mark.parametrize("policy, expected", [(None, "passive"), ("active", "active")])
def test_threaded_mpm_process_sleeps_when_idle_unless_told_otherwise(tmp_path, hybrid_programs, policy, expected):
    """A threaded MPM process whose OpenMP threads spin when idle takes the cores from LAMMPS's
    steps (mpm_solver/src/main.cpp): it restarts itself with OMP_WAIT_POLICY=passive, and keeps a
    policy the user set."""
    deck = deck_copy(tmp_path)
    log = tmp_path / "log.lammps"
    extra = {"OMP_NUM_THREADS": "2"}
    if policy is not None:
        extra["OMP_WAIT_POLICY"] = policy
    proc, _ = launch("-np", "1", str(deck), "-var", "nsteps", "20", "-var", "every", "10", "-log", str(log),
                     extra_env=extra)
    assert proc.returncode == 0, output(proc)
    assert re.search(rf"mpm_solver \S+ \(pid \d+, 2 OpenMP threads, OMP_WAIT_POLICY={expected}\) ready",
                     log.read_text()), log.read_text()


@pytest.mark.parametrize("np_", [1, 2])
def test_plugin_route_handshake_steps_and_clean_finish(tmp_path, hybrid_plugin, np_):
    deck = deck_copy(tmp_path)
    log = tmp_path / "log.lammps"
    proc, _ = launch("-np", str(np_), "--plugin", str(deck), "-var", "nsteps", "100", "-var", "every", "5",
                     "-log", str(log))
    text = output(proc)
    assert proc.returncode == 0, text
    assert "Loading plugin: fix hybrid/mpm" in text
    assert f"handshake ok with LAMMPS 29 Sep 2021 on {np_} rank(s)" in text
    assert "coupled run finished at LAMMPS step 100 after 20 exchange(s)" in text
    assert "fix hybrid/mpm: handshake ok with the MPM process" in log.read_text()


def test_launcher_composes_both_routes(tmp_path, hybrid_programs, hybrid_plugin):
    deck = deck_copy(tmp_path)
    proc, _ = launch("-np", "3", "--dry-run", str(deck), "-var", "nsteps", "5")
    assert proc.returncode == 0, output(proc)
    cmd = proc.stdout.strip()
    assert cmd.startswith(str(MPIRUN) + " -np 3 " + hybrid_programs["lmp_hybrid"] + f" -in {deck} -var nsteps 5 : ")
    assert cmd.endswith("-np 1 " + hybrid_programs["mpm_solver"] + " --coupled")
    proc, _ = launch("-np", "2", "--plugin", "--dry-run", str(deck))
    assert proc.returncode == 0, output(proc)
    assert f"{hybrid_plugin[0]} -m 0 -in " in proc.stdout


# ------------------------------------------------------------------------- input errors
@pytest.mark.parametrize("fix_args, message", [
    ("cell 0.01 bogus 3", "unknown keyword 'bogus'"),
    ("cell -0.01", "keyword 'cell' must be > 0"),
    ("cell 0.01 points_per_cell 5", "keyword 'points_per_cell' (points per cell and axis) must be 1 to 4"),
    ("cell 0.01 model granite", "keyword 'model' must be drucker_prager or mu_i, not 'granite'"),
    ("cell 0.01 timeout", "keyword 'timeout' needs a value"),
    ("cell 0.01 every 0", "keyword 'every' needs a positive integer"),
    ("cell 0.01 continuum nowhere", "continuum region 'nowhere' does not exist"),
    ("cell 0.01 adaptive 10 discrete nowhere", "discrete region 'nowhere' does not exist"),
    ("cell 0.01 discrete bed", "keyword 'discrete' needs adaptive zones (keyword 'adaptive')"),
    ("cell 0.01 weight 1.5", "keyword 'weight' (the share of a hybrid cell's mass its grains keep) must be between "
                             "0 and 1, not 1.5"),
    ("cell 0.01 wall friction", "keyword 'wall friction' needs the friction coefficient"),
    ("cell 0.01 container 0 INF", "keyword 'container' needs 4 values (xlo xhi ylo yhi; INF = the box face)"),
    ("cell 0.01 steps_per_contact 1.5", "keyword 'steps_per_contact' (warn below this many DEM steps per contact) "
                                        "must exceed pi/2, where velocity Verlet goes unstable, not 1.5"),
    ("cell 0.01 material no_such_material.toml", "keyword 'material': material file no_such_material.toml not found"),
    ("cell 0.01 relax -1", "keyword 'relax' (relaxation time of the velocity agreement, s; 0 = close the gap at "
                           "every exchange) must be >= 0, not -1"),
    ("cell 0.01 adaptive 10 touch floor", "keyword 'touch' needs a container face (xlo, xhi, ylo, yhi or all), "
                                          "not 'floor'"),
    ("cell 0.01 adaptive 10 touch ylo touch zlo", "keyword 'touch' face 'zlo' needs a 3D box (a 2D box has no z "
                                                  "faces)"),
    ("cell 0.01 adaptive 10 touch", "keyword 'touch' needs a value"),
    ("cell 0.01 touch ylo", "keyword 'touch' needs adaptive zones (keyword 'adaptive')"),
    ("cell 0.01 rezone_log verbose", "keyword 'rezone_log' must be full, summary or quiet, not 'verbose'"),
])
def test_bad_fix_line_is_a_lammps_error_naming_the_keyword(tmp_path, hybrid_programs, fix_args, message):
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(t, fix_args))
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert "ERROR: Illegal fix hybrid/mpm command: " + message in text, text
    # the MPM process is told at once instead of waiting for its handshake timeout
    assert ("mpm_solver: error: the DEM host ended before connecting: LAMMPS ended before fix hybrid/mpm "
            "connected (an error in the LAMMPS input before the first run") in text, text
    assert elapsed < STOP_WITHIN


def safe_step(share: float) -> float:
    """tc/20 of the handshake deck's stiffest pair (kn = 1000 N/m, gamma_n = 500 1/s, 2 mm grains
    of 2500 kg/m^3) at `share` of their mass: tc = pi / sqrt(kn/m_eff - gamma_n^2/4) (docs/design.md
    section 3), computed here independently of the fix."""
    m_eff = 0.5 * share * 2500 * 4 / 3 * math.pi * 0.001 ** 3
    return math.pi / math.sqrt(1000 / m_eff - 0.25 * 500 ** 2) / 20


def timestep_deck(tmp_path: Path, timestep: str, fix_args: str) -> Path:
    def edit(text):
        text = re.sub(r"^timestep\s.*$", f"timestep {timestep}", text, flags=re.M)
        text = with_fixed_faces(text)
        text = text.replace("fix             2d all", "region lower block INF INF INF 0.02 INF INF units box\n"
                                                     "fix             2d all")
        return replace_fix_line(text, fix_args)
    return deck_copy(tmp_path, edit)


@pytest.mark.parametrize("timestep, fix_args, share", [
    ("2.0e-4", "cell 0.01", 1.0),    # 1.1 steps per contact
    # grains in hybrid cells keep 10 % of their mass: their contacts are sqrt(10) times faster
    ("6.0e-5", "cell 0.01 continuum lower weight 0.1", 0.1),
])
def test_unstable_dem_time_step_is_refused_naming_the_safe_step(tmp_path, hybrid_programs, timestep, fix_args,
                                                                 share):
    """Below pi/2 steps per contact velocity Verlet cannot integrate the contact: refused."""
    proc, elapsed = launch("-np", "2", str(timestep_deck(tmp_path, timestep, fix_args)), "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    m = re.search(r"ERROR: Fix hybrid/mpm: the time step ([0-9.e+-]+) s is unstable \(checked before the run\): "
                  r".*fewer than pi/2.*Use timestep ([0-9.e+-]+) \(tc/20\) or less", text)
    assert m, text
    assert float(m.group(1)) == float(timestep)
    assert float(m.group(2)) == pytest.approx(safe_step(share), rel=1e-5)
    assert "mpm_solver: error: the DEM host ended before connecting" in text, text
    assert elapsed < STOP_WITHIN


@pytest.mark.parametrize("timestep, fix_args, warned", [
    ("5.0e-5", "cell 0.01", True),                             # 4.55 steps per contact: warned, runs
    ("1.0e-5", "cell 0.01", False),                            # 22.7: quiet
    ("1.0e-5", "cell 0.01 steps_per_contact 30", True),        # the user's own threshold
])
def test_poorly_resolved_dem_time_step_is_warned_and_runs(tmp_path, hybrid_programs, timestep, fix_args, warned):
    """Between pi/2 and the threshold (10, keyword steps_per_contact) the run goes on with a
    warning naming the safe step, as LIGGGHTS's check/timestep/gran does."""
    proc, _ = launch("-np", "2", str(timestep_deck(tmp_path, timestep, fix_args)), "-log", "none",
                     "-var", "nsteps", "20", timeout=60)
    text = output(proc)
    assert proc.returncode == 0, text
    m = re.search(r"WARNING: Fix hybrid/mpm: the time step ([0-9.e+-]+) s resolves the contacts poorly at the start "
                  r"of the run: .*Use timestep ([0-9.e+-]+) \(tc/20\) or less", text)
    assert bool(m) == warned, text
    if m:
        assert float(m.group(2)) == pytest.approx(safe_step(1.0), rel=1e-5)


def material_file(path: Path, dimension: int = 2, friction: float = 0.5, restitution: float | None = None) -> Path:
    """A calibrated material (the format of docs/design.md section 4.6) for the handshake
    deck's contact law unless told otherwise; restitution by default that of its mean pair."""
    if restitution is None:
        m_eff = 0.5 * 2500 * 4 / 3 * math.pi * 0.001 ** 3
        zeta = 500 / (2 * math.sqrt(1000 / m_eff))
        restitution = math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))
    path.write_text(f"""[material]
name = "test_grains"
dimension = {dimension}
[contact]
pair = "gran/hooke/history"
friction = {friction}
restitution = {restitution}
kt_over_kn = {2 / 7}
gammat_over_gamman = 0.5
polydispersity = 0.0
stiffness_number = 1000.0
[continuum]
packing_fraction = 0.82
critical_packing = 0.78
youngs_over_kn = 0.75
poisson = 0.2
mu_s = 0.3
mu_2 = 0.6
I0 = 0.3
friction_angle = 17.46
""")
    return path


def test_adaptive_zones_refuse_cells_under_two_grain_diameters(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(with_fixed_faces(t), "cell 0.0035 adaptive 10"))
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", "-var", "nsteps", "20", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert ("ERROR: Fix hybrid/mpm: cell 0.0035 is under 2 grain diameters (mean diameter 0.002): adaptive zones need "
            "cells that hold several grains. Use cell 0.004 or more") in text, text
    assert elapsed < STOP_WITHIN


def test_material_file_sets_the_continuum_from_the_deck_contact_law(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(t, f"cell 0.01 material {material_file(tmp_path / 'm.toml')}"))
    proc, _ = launch("-np", "2", str(deck), "-log", "none", "-var", "nsteps", "20", timeout=60)
    text = output(proc)
    assert proc.returncode == 0, text
    m = re.search(r"fix hybrid/mpm: material test_grains \(\S+\): Young's modulus (\S+) Pa, Poisson's ratio (\S+), "
                  r"friction angle (\S+) deg, mu_s ([0-9.e+-]+)", text)
    assert m, text
    assert float(m.group(1)) == pytest.approx(0.75 * 1000)    # E = youngs_over_kn * kn in 2D
    assert [float(g) for g in m.groups()[1:]] == [0.2, 17.46, 0.3]


@pytest.mark.parametrize("what, message", [
    ("friction", "was calibrated for another contact law (friction mu 0.5 in the deck, 0.3 in the calibration)"),
    ("restitution", "restitution of a mean-size pair"),
    ("dimension", "was calibrated in 3D, this run is 2D"),
    ("conflict", "keyword 'friction' conflicts with 'material'"),
])
def test_material_file_for_another_contact_law_is_refused(tmp_path, hybrid_programs, what, message):
    path = material_file(tmp_path / "m.toml", dimension=3 if what == "dimension" else 2,
                         friction=0.3 if what == "friction" else 0.5, restitution=0.5 if what == "restitution" else None)
    extra = " friction 30" if what == "conflict" else ""
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(t, f"cell 0.01 material {path}{extra}"))
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", "-var", "nsteps", "20", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert message in text, text
    assert elapsed < STOP_WITHIN


@pytest.mark.parametrize("touch", ["", "touch ylo", "touch all"])
def test_touched_floor_lets_the_continuum_reach_it(tmp_path, hybrid_programs, touch):
    """The deck's bed (3 cells deep) with adaptive zones, depth + band = 2 cells: only the bottom
    row lies deeper than that below the free top, so with the floor a discrete boundary (the
    default) nothing is continuum, and with the floor touched (`touch ylo`, or every face) the
    bottom row is, away from the side walls (6 of its 10 cells), or all of it (`touch all`). The
    faces travel to the MPM process in the handshake, which runs the oracle."""
    def edit(text):
        return replace_fix_line(with_fixed_faces(text), f"cell 0.01 adaptive 10 depth 0.012 band 0.008 {touch}")
    log = tmp_path / "log.lammps"
    proc, _ = launch("-np", "2", str(deck_copy(tmp_path, edit)), "-var", "nsteps", "20", "-log", str(log),
                     timeout=120)
    text = output(proc)
    assert proc.returncode == 0, text
    lammps_log = log.read_text()
    first = re.search(r"grid cells in the box: (\d+) continuum, (\d+) hybrid", lammps_log)
    assert first, lammps_log
    continuum = int(first.group(1))
    assert continuum == {"": 0, "touch ylo": 6, "touch all": 10}[touch], lammps_log
    faces = {"": None, "touch ylo": "ylo", "touch all": "xlo xhi ylo yhi"}[touch]
    if faces:
        assert f"the continuum may touch the container faces {faces} (" in lammps_log
    else:
        assert "may touch" not in lammps_log


TIMING_SECTIONS = ["Exchange", "MPM wait", "Apply", "Rezone", "Oracle", "Output", "Coupling"]


def timing_blocks(log_text: str) -> list[dict]:
    """The fix's timing breakdowns in a log: counts, one row (min, avg, max, %varavg, %total) per
    section, and its DEM-side line."""
    blocks = []
    lines = log_text.splitlines()
    for i, ln in enumerate(lines):
        m = re.match(r"fix hybrid/mpm timing breakdown \((\d+) exchanges, (\d+) rezones\):$", ln)
        if not m:
            continue
        assert lines[i + 1] == "Section |  min time  |  avg time  |  max time  |%varavg| %total", lines[i + 1]
        assert set(lines[i + 2]) == {"-"}, lines[i + 2]
        rows = {}
        for row in lines[i + 3:i + 3 + len(TIMING_SECTIONS)]:
            label, *values = [f.strip() for f in row.split("|")]
            rows[label] = [float(v) for v in values]
        blocks.append({"exchanges": int(m.group(1)), "rezones": int(m.group(2)), "rows": rows,
                       "dem": lines[i + 3 + len(TIMING_SECTIONS)]})
    return blocks


def test_every_auto_exchanges_at_the_continuums_stable_substep(tmp_path, hybrid_programs):
    """`every auto`: the fix sets the exchange interval to the continuum's stable substep in whole
    DEM steps and rounds the oracle's 12 steps up to a multiple of it. This deck's disks (LAMMPS
    masses of 2500 kg/m^3 spheres: 4/3 r rho = 3.333 kg/m^2 per unit depth), a continuum given
    youngs 1.3e4 and poisson 0.3 at the nominal packing 0.6, 0.01 m cells and cfl 0.5: a substep
    of 5.35 DEM steps of 1e-5 s, so every 5 and the oracle every 15; the MPM process then takes one
    or two substeps per exchange (its points made from grains are denser than nominal, its hybrid
    points lighter). With the fix's default constants (youngs 1e7) the substep is under one DEM
    step, and `every auto` exchanges every step."""
    def edit(text):
        text = replace_fix_line(with_fixed_faces(text), "cell 0.01 every auto youngs 1.3e4 adaptive 12 depth 0.012 band 0.008 touch ylo")
        text = text.replace("thermo          50", "thermo          10")
        out = text.replace("thermo_style    custom step atoms ke f_couple", "thermo_style    custom step atoms ke f_couple[1] f_couple[6]")
        assert out != text
        return out
    log = tmp_path / "log.lammps"
    deck = deck_copy(tmp_path, edit)
    proc, _ = launch("-np", "2", str(deck), "-var", "nsteps", "40", "-log", str(log), timeout=120)
    text = output(proc)
    assert proc.returncode == 0, text
    lammps_log = log.read_text()
    modulus = 1.3e4 * 0.7 / (1.3 * 0.4)                                  # lambda + 2G
    speed = math.sqrt(modulus / (0.6 * 4 / 3 * 0.001 * 2500))
    every = int(0.5 * 0.01 / speed / 1e-5)
    assert every == 5
    assert (f"fix hybrid/mpm: exchange every {every} step(s) (every auto: the continuum's stable substep cfl dx / c = "
            f"0.5 x 0.01 m / {speed:.4g} m/s") in lammps_log, lammps_log
    assert "zone oracle every 15 steps (keyword 'adaptive' 12 rounded up to a multiple of it)" in lammps_log, lammps_log
    assert f"exchange every {every} step(s)\n" in lammps_log, lammps_log           # the handshake's line
    blocks = timing_blocks(lammps_log)
    assert [b["exchanges"] for b in blocks] == [40 // every], lammps_log
    rows = [ln.split() for ln in lammps_log.splitlines() if re.match(r"^\s+\d+\s+\d+\s+\S+\s+\d+\s+\d+\s*$", ln)]
    substeps = {int(r[0]): int(r[4]) for r in rows if int(r[0]) > 0}
    assert set(substeps) == {10, 20, 30, 40}, lammps_log
    assert all(1 <= n <= 2 for n in substeps.values()), substeps
    assert int(rows[-1][3]) == 40 // every, rows                        # completed exchanges


def test_timing_breakdown_at_the_end_of_every_run_and_in_the_thermo_vector(tmp_path, hybrid_programs):
    """Two coupled runs with adaptive zones on 2 ranks: each ends with the fix's timing breakdown
    in LAMMPS's columns, whose sections add up to the coupling's total, a share of the run's wall
    time; thermo prints entries 30-33, non-negative, the cumulative ones never decreasing."""
    def edit(text):
        text = replace_fix_line(with_fixed_faces(text),
                                "cell 0.01 every 5 adaptive 10 depth 0.012 band 0.008 touch ylo")
        text = text.replace("thermo          50", "thermo          10")
        out = text.replace("thermo_style    custom step atoms ke f_couple",
                           "thermo_style    custom step atoms ke f_couple f_couple[30] f_couple[31] f_couple[32] "
                           "f_couple[33]")
        assert out != text
        return out
    log = tmp_path / "log.lammps"
    deck = deck_copy(tmp_path, edit, extra="\nrun             20\n")
    proc, _ = launch("-np", "2", str(deck), "-var", "nsteps", "40", "-log", str(log), timeout=120)
    text = output(proc)
    assert proc.returncode == 0, text
    lammps_log = log.read_text()
    blocks = timing_blocks(lammps_log)
    assert len(blocks) == 2, lammps_log
    # 40 steps every 5 (8 exchanges), then 20 more (4, the first step not an exchange step of its own)
    assert [b["exchanges"] for b in blocks] == [8, 4], lammps_log
    assert blocks[0]["rezones"] >= 1, lammps_log                 # the conversion, then the oracle's
    for b in blocks:
        rows = b["rows"]
        assert list(rows) == TIMING_SECTIONS, rows
        for label, (tmin, tavg, tmax, varavg, percent) in rows.items():
            assert 0.0 <= tmin <= tavg * (1 + 1e-4) + 1e-9 and tavg <= tmax * (1 + 1e-4) + 1e-9, (label, rows)
            assert varavg >= 0.0 and 0.0 <= percent <= 100.0, (label, rows)
        total = rows["Coupling"]
        sections = [rows[s] for s in TIMING_SECTIONS[:-1]]
        # the sections add up to the coupling's total (5 significant digits, 2 decimals of %)
        assert sum(r[1] for r in sections) == pytest.approx(total[1], rel=1e-3, abs=1e-4), rows
        assert sum(r[4] for r in sections) == pytest.approx(total[4], abs=0.05), rows
        assert all(r[1] <= total[1] * (1 + 1e-4) for r in sections), rows
        assert total[1] > 0.0 and rows["MPM wait"][1] > 0.0, rows
        m = re.match(r"DEM side \(LAMMPS timer, avg\): Pair (\S+) Neigh (\S+) Comm (\S+) Modify (\S+) s; "
                     r"coupling (\S+) s of (\S+) s wall \((\S+)%, part of Modify\)$", b["dem"])
        assert m, b["dem"]
        pair, neigh, comm, modify, coupling, wall, share = (float(g) for g in m.groups())
        assert min(pair, neigh, comm, modify) >= 0.0
        assert coupling == pytest.approx(total[1], rel=1e-3, abs=1e-4) and coupling <= wall
        assert share == pytest.approx(total[4], abs=0.01) and 0.0 < share <= 100.0
    # the first run's rezones (with the oracle) are in its block
    assert blocks[0]["rows"]["Rezone"][1] > 0.0, blocks[0]
    # thermo: entries 30-33 on every thermo line of both runs
    header = "Step Atoms KinEng f_couple f_couple[30] f_couple[31] f_couple[32] f_couple[33]".split()
    rows = []
    lines = lammps_log.splitlines()
    for i, ln in enumerate(lines):
        if ln.split() == header:
            for row in lines[i + 1:]:
                if row.startswith("Loop time"):
                    break
                fields = row.split()
                if len(fields) == len(header) and fields[0].isdigit():    # (rezone lines between)
                    rows.append([float(f) for f in fields])
    assert [int(r[0]) for r in rows] == list(range(0, 41, 10)) + [40, 50, 60], lammps_log
    coupling, wait, rezone, share = (np.array([r[k] for r in rows]) for k in (4, 5, 6, 7))
    assert (coupling >= 0).all() and (wait >= 0).all() and (rezone >= 0).all(), rows
    assert (np.diff(coupling) >= 0).all() and (np.diff(wait) >= 0).all() and (np.diff(rezone) >= 0).all(), rows
    assert (wait + rezone <= coupling * (1 + 1e-9)).all(), rows
    assert coupling[-1] > coupling[0] and wait[-1] > 0, rows
    assert ((share >= 0) & (share <= 100)).all() and share[-1] > 0, rows


def test_bad_fix_line_through_the_plugin(tmp_path, hybrid_plugin):
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(t, "cell 0.01 bogus 3"))
    proc, elapsed = launch("-np", "2", "--plugin", str(deck), "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert "ERROR: Illegal fix hybrid/mpm command: unknown keyword 'bogus'" in text, text
    assert "mpm_solver: error: the DEM host ended before connecting" in text, text
    assert elapsed < STOP_WITHIN


@pytest.mark.parametrize("plugin", [False, True], ids=["lmp_hybrid", "plugin"])
def test_lammps_error_during_the_coupled_run_stops_the_mpm_process(tmp_path, hybrid_programs, plugin, request):
    if plugin:
        request.getfixturevalue("hybrid_plugin")
    deck = deck_copy(tmp_path, extra="\nno_such_command 1\n")
    proc, elapsed = launch("-np", "2", *(["--plugin"] if plugin else []), str(deck), "-var", "nsteps", "50",
                           "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert "ERROR: Unknown command: no_such_command" in text
    assert "mpm_solver: error: LAMMPS stopped the coupled run after 5 exchange(s)" in text, text
    assert elapsed < STOP_WITHIN


@pytest.mark.parametrize("plugin", [False, True], ids=["lmp_hybrid", "plugin"])
def test_deck_without_the_fix_ends_the_mpm_process_with_a_reason(tmp_path, hybrid_programs, plugin, request):
    if plugin:
        request.getfixturevalue("hybrid_plugin")
    deck = deck_copy(tmp_path, lambda t: re.sub(r"^fix\s+couple.*$", "", t, flags=re.M).replace(" f_couple", ""))
    proc, elapsed = launch("-np", "1", *(["--plugin"] if plugin else []), str(deck), "-var", "nsteps", "20",
                           "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert "mpm_solver: error: the DEM host ended before connecting" in text, text
    assert elapsed < STOP_WITHIN


def test_version_mismatch_is_an_error_on_both_sides_naming_both_versions(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path)
    cmd = [str(MPIRUN), "-np", "1", hybrid_programs["lmp_hybrid"], "-in", str(deck), "-log", "none",
           ":", "-np", "1", "env", "HYBRID_COUPLER_FAKE_RELEASE=9.9.9", hybrid_programs["mpm_solver"], "--coupled"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, env=env())
    text = output(proc)
    assert proc.returncode != 0, text
    both = f"fix hybrid/mpm is release 0.1.0 (protocol {PROTOCOL}), mpm_solver is release 9.9.9 (protocol {PROTOCOL})"
    assert f"mpm_solver: error: version mismatch: {both}" in text, text
    assert f"ERROR: Fix hybrid/mpm: the MPM process refused the connection: version mismatch: {both}" in text


def test_cell_larger_than_the_box_is_refused_at_the_handshake(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(t, "cell 0.08"))
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    message = "the grid cell size 0.080000 m is more than half the box along x (0.100000 m): choose a smaller 'cell'"
    assert "ERROR: Fix hybrid/mpm: the MPM process refused the connection: " + message in text, text
    assert elapsed < STOP_WITHIN


@pytest.mark.parametrize("case, message", [
    # this 2D deck's `set density` gives its disks a sphere's mass: 4/3 r rho per unit area; one disk
    # shrunk by `set diameter` keeps its mass, 1 / 0.8^2 the others' per unit area
    ("mixed", "ERROR: Fix hybrid/mpm: the group's grains have solid densities from 3.333 to 5.208 (per unit area: "
              "mass over pi r^2), but grains and material points convert at one solid density"),
    ("given", "ERROR: Fix hybrid/mpm: grain_density 2500 is not the group's grains' own solid density 3.333 "
              "(per unit area: mass over pi r^2)"),
])
def test_grains_of_another_solid_density_are_refused(tmp_path, hybrid_programs, case, message):
    def edit(text: str) -> str:
        if case == "mixed":
            out = text.replace("set             type 1 density 2500\n",
                               "set             type 1 density 2500\nset             atom 1 diameter 0.0016\n")
            assert out != text
            return out
        return replace_fix_line(text, "cell 0.01 grain_density 2500")
    proc, elapsed = launch("-np", "2", str(deck_copy(tmp_path, edit)), "-log", "none", "-var", "nsteps", "20",
                           timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert message in text, text
    if case == "mixed":
        assert "set density/disc" in text, text
    assert elapsed < STOP_WITHIN


def test_unwritable_output_directory_is_a_clear_error(tmp_path, hybrid_programs):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the output directory should go")
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(t, f"cell 0.01 output {blocker}/frames 1"))
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", "-var", "nsteps", "20", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert "the MPM process could not set up the continuum: cannot create output directory" in text, text
    assert elapsed < STOP_WITHIN


@pytest.mark.parametrize("fault, lammps_says, mpm_says", [
    # a std::runtime_error while the exchange is computed: reported in that exchange's answer
    ("exchange@30", "the MPM process reported an error at step 30: the continuum failed at step 30: test fault "
                    "HYBRID_MPM_TEST_FAULT=exchange@30 at step 30 (std::runtime_error)",
     "mpm_solver: error: the continuum failed at step 30: test fault HYBRID_MPM_TEST_FAULT=exchange@30 at step 30 "
     "(std::runtime_error)"),
    # one in the work after the acknowledgement: reported at the next exchange
    ("after@30", "the MPM process reported an error at step 40: the continuum failed after step 30: test fault "
                 "HYBRID_MPM_TEST_FAULT=after@30 at step 30 (std::runtime_error)",
     "mpm_solver: error: the continuum failed after step 30: test fault"),
    # not a std::exception, outside the exchange's own handlers
    ("unknown@30", "the MPM process reported an error at step 30: the MPM process failed at step 30: an exception of "
                   "unknown type (not a std::exception)",
     "mpm_solver: error: the MPM process failed at step 30: an exception of unknown type"),
])
def test_any_exception_in_the_mpm_process_stops_lammps_naming_it(tmp_path, hybrid_programs, fault, lammps_says,
                                                                  mpm_says):
    """Not only UserErrors: any failure of the coupled loop reaches LAMMPS at once (not after its
    reply timeout), with the cause, and both programs exit non-zero."""
    deck = deck_copy(tmp_path)
    cmd = [str(MPIRUN), "-np", "2", hybrid_programs["lmp_hybrid"], "-in", str(deck), "-log", "none",
           "-var", "nsteps", "100", ":", "-np", "1", "env", f"HYBRID_MPM_TEST_FAULT={fault}",
           hybrid_programs["mpm_solver"], "--coupled"]
    t0 = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=90, env=env())
    elapsed = time.monotonic() - t0
    text = output(proc)
    assert proc.returncode != 0, text
    assert "ERROR: Fix hybrid/mpm: " + lammps_says in text, text
    assert mpm_says in text, text
    assert "no reply from the MPM process" not in text, text
    assert elapsed < STOP_WITHIN, text


TRICLINIC = ("ERROR: Fix hybrid/mpm: the simulation box is triclinic, but the MPM grid needs an orthogonal box (its "
             "cells are axis-aligned); use an orthogonal box (change_box all ortho)")


def test_triclinic_box_is_refused_when_the_fix_is_defined(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path, lambda t: re.sub(r"^(fix\s+couple\s)", r"change_box all triclinic\n\1", t, flags=re.M))
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert TRICLINIC in text, text
    assert "mpm_solver: error: the DEM host ended before connecting" in text, text
    assert elapsed < STOP_WITHIN


def test_box_tilted_between_runs_is_refused(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path, extra="\nchange_box all triclinic\nrun 10\n")
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", "-var", "nsteps", "20", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert TRICLINIC in text, text
    assert "mpm_solver: error: LAMMPS stopped the coupled run after 2 exchange(s)" in text, text
    assert elapsed < STOP_WITHIN


@pytest.mark.parametrize("magnitude, refused", [("5.0", True), ("9.81", False)])
def test_gravity_changed_between_runs_is_refused(tmp_path, hybrid_programs, magnitude, refused):
    """The MPM process takes gravity once, at the handshake: a later run with another gravity is
    an error naming both; the same gravity redefined runs on."""
    extra = f"\nunfix grav\nfix grav all gravity {magnitude} vector 0 -1 0\nrun 10\n"
    proc, elapsed = launch("-np", "2", str(deck_copy(tmp_path, extra=extra)), "-log", "none", "-var", "nsteps", "20",
                           timeout=60)
    text = output(proc)
    if not refused:
        assert proc.returncode == 0, text
        assert "coupled run finished at LAMMPS step 30 after 3 exchange(s)" in text, text
        return
    assert proc.returncode != 0, text
    assert ("ERROR: Fix hybrid/mpm: gravity changed since the coupled run started: (0, -9.81, 0) m/s^2 then, "
            "(0, -5, 0) now") in text, text
    assert "mpm_solver: error: LAMMPS stopped the coupled run after 2 exchange(s)" in text, text
    assert elapsed < STOP_WITHIN


def test_deleted_stress_compute_is_a_clear_error(tmp_path, hybrid_programs):
    """Adaptive zones use the fix's compute stress/atom at every run's setup: deleting it between
    runs is an error naming it (it used to index the compute list with -1)."""
    deck = deck_copy(tmp_path, lambda t: replace_fix_line(with_fixed_faces(t), "cell 0.01 adaptive 10 every 10"),
                     extra="\nuncompute couple_hybrid_stress\nrun 10\n")
    proc, elapsed = launch("-np", "2", str(deck), "-log", "none", "-var", "nsteps", "20", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert ("ERROR: Fix hybrid/mpm: its compute couple_hybrid_stress (stress/atom, for the stress of new material "
            "points) no longer exists: do not uncompute it while the fix is defined") in text, text
    assert elapsed < STOP_WITHIN


# ---------------------------------------------------------------------------- no peer
def test_lmp_hybrid_without_mpm_process_is_a_clear_error(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path)
    t0 = time.monotonic()
    proc = subprocess.run([str(MPIRUN), "-np", "2", hybrid_programs["lmp_hybrid"], "-in", str(deck), "-log", "none"],
                          capture_output=True, text=True, timeout=60, env=env())
    text = output(proc)
    assert proc.returncode != 0, text
    assert "ERROR: Fix hybrid/mpm: no MPM process in this MPI job" in text
    assert "mpm_solver --coupled" in text
    assert time.monotonic() - t0 < STOP_WITHIN


def test_mpm_solver_coupled_without_lammps_is_a_clear_error(hybrid_programs):
    proc = subprocess.run([hybrid_programs["mpm_solver"], "--coupled"], capture_output=True, text=True, timeout=60,
                          env=env())
    assert proc.returncode == 2, output(proc)
    assert "no DEM host process in this MPI job" in proc.stderr


def test_mpm_solver_in_an_mpmd_job_without_coupled_refuses(tmp_path, hybrid_programs):
    deck = deck_copy(tmp_path)
    scene = tmp_path / "scene.toml"    # refused before it is read
    scene.write_text("dimension = 2\n")
    cmd = [str(MPIRUN), "-np", "1", hybrid_programs["lmp_hybrid"], "-in", str(deck), "-log", "none",
           ":", "-np", "1", hybrid_programs["mpm_solver"], str(scene)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, env=env())
    assert proc.returncode != 0
    assert "without --coupled" in output(proc)


# -------------------------------------------------------------- peer death and hangs
class Job(BackgroundJob):
    """A coupled job in the background; its output collected by a thread."""

    def __init__(self, tmp_path: Path, *vars_: str, np_: int = 2):
        self.deck = deck_copy(tmp_path)
        super().__init__([sys.executable, str(LAUNCH), "-np", str(np_), str(self.deck), "-log", "none",
                          "-var", "nsteps", "100000000", *vars_], env=env())

    def wait_for(self, pattern: str, timeout: float = 60) -> re.Match:
        m = super().wait_for(pattern, timeout)
        if m is None:
            raise AssertionError(f"no '{pattern}' in the output:\n{self.text}")
        return m

    def running(self) -> int:
        """Waits until both sides are coupled and exchanging; returns the mpm_solver pid."""
        pid = int(self.wait_for(r"mpm_solver: coupled mode, .* pid (\d+)").group(1))
        self.wait_for(r"fix hybrid/mpm: handshake ok")
        self.wait_for(r"mpm_solver: handshake ok")
        time.sleep(1.0)   # well into the run
        assert self.proc.poll() is None, self.text
        return pid

    def lammps_pids(self) -> list[int]:
        """LAMMPS ranks of this job: lmp_hybrid processes whose command line names our deck."""
        pids = []
        for p in Path("/proc").iterdir():
            if not p.name.isdigit():
                continue
            try:
                argv = (p / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if argv and argv[0].endswith(b"lmp_hybrid") and str(self.deck).encode() in argv:
                pids.append(int(p.name))
        return pids

    def finish(self, timeout: float) -> tuple[int, float]:
        t0 = time.monotonic()
        rc = self.wait(timeout)
        if rc is None:
            self.kill()
            raise AssertionError(f"the job did not stop within {timeout} s:\n{self.text}")
        return rc, time.monotonic() - t0


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.fixture
def job_factory(tmp_path, hybrid_programs):
    jobs: list[Job] = []

    def make(*vars_: str, np_: int = 2) -> Job:
        job = Job(tmp_path, *vars_, np_=np_)
        jobs.append(job)
        return job

    yield make
    for job in jobs:
        job.kill()


def test_killing_the_mpm_process_stops_the_job(job_factory):
    job = job_factory("-var", "every", "1")
    mpm_pid = job.running()
    lammps = job.lammps_pids()
    assert len(lammps) == 2, job.text
    os.kill(mpm_pid, signal.SIGKILL)
    rc, elapsed = job.finish(STOP_WITHIN)
    assert rc != 0, job.text
    assert "exited on signal 9 (Killed)" in job.text      # mpirun's message
    assert "rank 2 is mpm_solver" in job.text              # hybrid_launch's translation
    time.sleep(0.5)
    assert not any(alive(p) for p in lammps), "LAMMPS ranks survived"


def test_killing_lammps_stops_the_mpm_process(job_factory):
    job = job_factory("-var", "every", "1")
    mpm_pid = job.running()
    lammps = job.lammps_pids()
    assert lammps, job.text
    os.kill(lammps[0], signal.SIGKILL)
    rc, elapsed = job.finish(STOP_WITHIN)
    assert rc != 0, job.text
    assert "exited on signal 9 (Killed)" in job.text
    time.sleep(0.5)
    assert not alive(mpm_pid), "mpm_solver survived"


def test_hung_mpm_process_times_out_in_lammps(job_factory):
    job = job_factory("-var", "every", "1", "-var", "timeout", "3")
    mpm_pid = job.running()
    os.kill(mpm_pid, signal.SIGSTOP)
    try:
        rc, elapsed = job.finish(STOP_WITHIN)
    finally:
        if alive(mpm_pid):
            os.kill(mpm_pid, signal.SIGKILL)
    assert rc != 0, job.text
    # stopped while LAMMPS waited for an acknowledgement, or while it sent a step header
    assert re.search(r"ERROR: Fix hybrid/mpm: (no reply from the MPM process within 3 s while waiting for the "
                     r"(acknowledgement|node velocities) of step \d+; it may have crashed or hung - check its output|"
                     r"could not deliver the (step header|grain node sums) of step \d+ to the MPM process within 3 s)",
                     job.text), job.text
    assert "fix hybrid/mpm: the MPM process does not respond; aborting the MPI job" in job.text


def test_hung_lammps_times_out_in_the_mpm_process(job_factory):
    job = job_factory("-var", "every", "1", "-var", "idle", "3")
    job.running()
    lammps = job.lammps_pids()
    for pid in lammps:
        os.kill(pid, signal.SIGSTOP)
    try:
        rc, elapsed = job.finish(STOP_WITHIN)
    finally:
        for pid in lammps:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert rc != 0, job.text
    # stopped while the MPM process waited for the next step or for a rank's part of an exchange
    # (the ranks are stopped one after the other), or while it sent an acknowledgement
    assert re.search(r"mpm_solver: error: (no reply from LAMMPS within 3 s while waiting for (the next message "
                     r"from fix hybrid/mpm|.* from LAMMPS rank \d+)|could not deliver the acknowledgement of step \d+ "
                     r"to LAMMPS within 3 s).*; aborting the MPI job", job.text), job.text
