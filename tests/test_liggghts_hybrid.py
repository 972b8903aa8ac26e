"""LIGGGHTS 3.8 as the DEM host (liggghts_hybrid, tools/hybrid_launch.py --host liggghts): what it
does not support yet is refused with an error naming the problem and what to do, and the MPM
process is told at once; an error during the coupled run stops both sides. (Its conservation
tests are the LAMMPS host's, parametrised: tests/test_coupled_physics.py.)
"""
from __future__ import annotations

import math
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import REPO
from hgtools.logs import thermo_tables
from test_coupled_physics import liggghts_headers
from test_coupled_launch import LAUNCH, STOP_WITHIN, TIMING_SECTIONS, env, material_file, output, timing_blocks

DECK = REPO / "input_decks" / "hybrid" / "momentum_3d.liggghts"

# a 2D box and the fix, nothing else (the fix refuses 2D when it is defined)
DECK_2D = """units si
atom_style sphere
dimension 2
boundary f f p
region box block 0 0.1 0 0.1 -0.002 0.002 units box
create_box 1 box
fix couple all hybrid/mpm cell 0.01
"""


def launch(*args: str, timeout: float = 60, cwd: Path | None = None) -> tuple[subprocess.CompletedProcess, float]:
    """tools/hybrid_launch.py; the output is read with undecodable bytes replaced: after an error
    in a coupled job LIGGGHTS prints its message a second time from freed memory."""
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, str(LAUNCH), *args], capture_output=True, text=True, errors="replace",
                          timeout=timeout, env=env(), cwd=cwd)
    return proc, time.monotonic() - t0


@pytest.fixture(scope="module")
def liggghts_hybrid(hybrid_programs) -> str:
    exe = hybrid_programs.get("liggghts_hybrid", "")
    if not exe or not Path(exe).exists():
        pytest.fail("liggghts_hybrid is not built: libliggghts-dev was not found at configure time (tools/setup.sh)")
    return exe


def edited_deck(tmp_path: Path, edit) -> Path:
    deck = tmp_path / "deck.liggghts"
    deck.write_text(edit(DECK.read_text()))
    return deck


def sub(pattern: str, new: str):
    def edit(text: str) -> str:
        out = re.sub(pattern, new, text, flags=re.M)
        assert out != text, pattern
        return out
    return edit


@pytest.mark.parametrize("edit, message", [
    (lambda _: DECK_2D, "LIGGGHTS runs are 3D only"),
    # spheres_3d was calibrated for the silo's grains (restitution 0.5), not these
    (sub(r"youngs 1.0e5$", "material spheres_3d"), "material " + str(REPO / "input_decks" / "materials" /
                                                                      "spheres_3d.toml") +
     " was calibrated for another contact law (restitution of a mean-size pair 0.988698 in the deck, 0.5 in the "
     "calibration)"),
    (sub(r"^pair_style .*$\n^pair_coeff .*$", "pair_style soft 0.004\npair_coeff * * 1.0"),
     "pair style soft is not a granular one: use pair_style gran model hooke (or hertz) tangential history"),
    (sub(r"youngs 1.0e5$", "youngs 1.0e5 grain_density 2600"),
     "grain_density 2600 is not the group's grains' own solid density 2500 (mass over 4/3 pi r^3)"),
], ids=["2d", "material_of_another_law", "pair_style", "grain_density"])
def test_liggghts_refuses_what_it_does_not_support_naming_it(tmp_path, liggghts_hybrid, edit, message):
    deck = edited_deck(tmp_path, edit)
    proc, elapsed = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "20", "-log", "none",
                           timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert "ERROR: Fix hybrid/mpm: " + message in text, text
    # the MPM process is told at once instead of waiting for its handshake timeout
    # the MPM process cannot know its host before the handshake: the host's own note names it
    assert ("mpm_solver: error: the DEM host ended before connecting: LIGGGHTS ended before fix hybrid/mpm connected "
            "(an error in the LIGGGHTS input before the first run") in text, text
    assert elapsed < STOP_WITHIN


def test_liggghts_error_during_the_coupled_run_stops_the_mpm_process(tmp_path, liggghts_hybrid):
    deck = edited_deck(tmp_path, lambda t: t + "\nno_such_command 1\n")
    proc, elapsed = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "50", "-var", "every", "10",
                           "-log", "none", timeout=60)
    text = output(proc)
    assert proc.returncode != 0, text
    assert "ERROR: Unknown command: no_such_command" in text, text
    assert ("mpm_solver: error: LIGGGHTS stopped the coupled run after 5 exchange(s): LIGGGHTS stopped on an error "
            "during the coupled run - see the LIGGGHTS output for the ERROR line") in text, text
    assert "ranks 0-1 are LIGGGHTS (liggghts_hybrid), rank 2 is mpm_solver" in text, text
    assert elapsed < STOP_WITHIN


# the momentum deck with LIGGGHTS's Young's-modulus models instead of hooke/stiffness
ELASTIC = ("fix             m1 all property/global youngsModulus peratomtype 5e6\n"
           "fix             m6 all property/global poissonsRatio peratomtype 0.3\n"
           "fix             m7 all property/global coefficientRestitution peratomtypepair 1 0.5\n"
           "fix             m8 all property/global characteristicVelocity scalar 0.1")


def with_model(model: str, timestep: str):
    def edit(text: str) -> str:
        text = re.sub(r"^timestep .*$", f"timestep        {timestep}", text, flags=re.M)
        if model == "hooke/stiffness":
            return text
        text = sub(r"^fix             m1 .*$", ELASTIC)(text)
        return sub(r"model hooke/stiffness tangential", f"model {model} tangential")(text)
    return edit


@pytest.mark.parametrize("model, timestep, says", [
    # kn = 2000 N/m, the lightest grains at their hybrid share 0.5 (4.19e-5 kg): tc = 3.21e-4 s
    ("hooke/stiffness", "1.0e-5", "fix hybrid/mpm: DEM time step 1e-05 s: the stiffest contact (pair style gran model "
                                  "hooke/stiffness: kn = 2000 N/m, kt = 571.4 N/m, gamma_n = 50 1/s; lightest grains "
                                  "4.18879e-05 kg, at their share in hybrid cells) lasts tc = 0.000321489 s, 32.1 steps "
                                  "per contact"),
    ("hooke/stiffness", "5.0e-5", "WARNING: Fix hybrid/mpm: the time step 5e-05 s resolves the contacts poorly at the "
                                  "start of the run"),
    ("hooke/stiffness", "3.0e-4", "ERROR: Fix hybrid/mpm: the time step 0.0003 s is unstable (checked before the run)"),
    # E = 5 MPa, nu = 0.3: twice the Rayleigh time (1.73e-4 s) is shorter than the Hertz time
    ("hertz", "1.0e-5", "have the Hertz time 0.0007694 s at relative speed 0.168 m/s and the Rayleigh time 0.0001731 s"),
    ("hooke", "1.0e-5", "(pair style gran model hooke, 4.189e-05 kg at their share in hybrid cells, E 5e+06 Pa"),
    ("hertz", "4.0e-4", "ERROR: Fix hybrid/mpm: the time step 0.0004 s is unstable (checked before the run): the "
                        "lightest grains (pair style gran model hertz"),
])
def test_liggghts_time_step_is_checked_against_its_contact_model(tmp_path, liggghts_hybrid, model, timestep, says):
    """The DEM step against LIGGGHTS's contact models: hooke/stiffness as LAMMPS's gran/hooke/history
    (its kn, kt, gamma_n), hooke and hertz through the Hertz and Rayleigh times of LIGGGHTS's fix
    check/timestep/gran; fewer than pi/2 steps per contact are refused naming the safe step."""
    deck = edited_deck(tmp_path, with_model(model, timestep))
    proc, elapsed = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "10", "-log", "none",
                           cwd=tmp_path)
    text = output(proc)
    assert says in text, text
    assert (proc.returncode != 0) == says.startswith("ERROR"), text
    if proc.returncode != 0:
        assert "mpm_solver: error: the DEM host ended before connecting" in text, text
        assert elapsed < STOP_WITHIN
    else:
        assert "fix hybrid/mpm: finished the coupled run after 10 exchange(s)" in text, text
        assert "handshake ok with LIGGGHTS 3.8.0" in text, text    # the MPM process names its host
        assert "mpm_solver: coupled run finished at LIGGGHTS step 10 after 10 exchange(s)" in text, text


def test_liggghts_restart_continues_the_coupled_run(tmp_path, liggghts_hybrid):
    """A coupled LIGGGHTS run that writes a restart file at step 30 (the MPM process saves its state
    next to it) and a second job that reads both (keyword mpm_state) reach the same totals at step
    60 as the uninterrupted run; without mpm_state the restarted job is refused, naming the keyword."""
    full = DECK.read_text()
    marker = "run             ${nsteps}"
    assert marker in full
    straight, restarted, refused = (tmp_path / name for name in ("straight", "restarted", "refused"))
    for d in (straight, restarted, refused):
        d.mkdir()
    (straight / "deck.in").write_text(full.replace(marker, "run 30\nwrite_restart restart.bin\nrun 30\n"))
    proc, _ = launch("--host", "liggghts", "-np", "2", "deck.in", "-log", "log.lammps", cwd=straight)
    assert proc.returncode == 0, output(proc)
    log_a = liggghts_headers((straight / "log.lammps").read_text(), full)
    assert "MPM state saved to restart.bin.mpm.h5 (512 material points)" in log_a
    # what LIGGGHTS's restart file does not keep: the settings, the material fixes, the pair style
    kept_lines = [ln for ln in full.splitlines() if ln.startswith((
        "variable every", "variable pic", "newton", "communicate", "fix             m", "pair_", "neighbor", "neigh_",
        "timestep", "fix             integ", "region          core", "fix             couple", "thermo"))]
    deck_b = "read_restart    restart.bin\n" + "\n".join(kept_lines) + "\nrun 30\n"
    for d, state in ((restarted, " mpm_state restart.bin.mpm.h5"), (refused, "")):
        for name in ("restart.bin", "restart.bin.mpm.h5"):
            (d / name).write_bytes((straight / name).read_bytes())
        (d / "deck.in").write_text(re.sub(r"^(fix\s+couple .*)$", r"\1" + state, deck_b, flags=re.M))
    proc, _ = launch("--host", "liggghts", "-np", "2", "deck.in", "-log", "log.lammps", cwd=restarted)
    assert proc.returncode == 0, output(proc)
    log_b = liggghts_headers((restarted / "log.lammps").read_text(), full)
    assert "MPM state loaded from restart.bin.mpm.h5 (512 material points)" in log_b
    a = [r for r in thermo_tables(log_a)[-1] if r["Step"] == 60][-1]
    b = [r for r in thermo_tables(log_b)[-1] if r["Step"] == 60][-1]
    scale = a["f_couple[8]"] * 0.05
    for col in ("f_couple[9]", "f_couple[10]", "f_couple[11]"):
        assert abs(a[col] - b[col]) <= 1e-13 * scale, (col, a[col], b[col])
    for col in ("f_couple[2]", "f_couple[3]", "f_couple[8]", "f_couple[5]"):
        assert a[col] == pytest.approx(b[col], rel=1e-12), col
    proc, elapsed = launch("--host", "liggghts", "-np", "2", "deck.in", "-log", "none", cwd=refused)
    assert proc.returncode != 0 and elapsed < STOP_WITHIN, output(proc)
    assert "ERROR: Fix hybrid/mpm: the restart file was written after grains became material points; add the " \
           "keyword 'mpm_state FILE'" in output(proc), output(proc)


def test_liggghts_gravity_changed_between_runs_is_refused(tmp_path, liggghts_hybrid):
    """The MPM process takes gravity once, at the handshake: a later run with gravity added is an
    error naming both, and the MPM process is told."""
    deck = edited_deck(tmp_path, lambda t: t + "\nfix grav all gravity 5.0 vector 0 -1 0\nrun 10\n")
    proc, elapsed = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "20", "-var", "every", "10",
                           "-log", "none")
    text = output(proc)
    assert proc.returncode != 0, text
    assert ("ERROR: Fix hybrid/mpm: gravity changed since the coupled run started: (0, 0, 0) m/s^2 then, "
            "(0, -5, 0) now") in text, text
    assert "mpm_solver: error: LIGGGHTS stopped the coupled run after 2 exchange(s)" in text, text
    assert elapsed < STOP_WITHIN


def liggghts_material(path: Path) -> Path:
    """A calibrated material for the momentum deck's contact law (hooke/stiffness: kn 2000 N/m,
    kt 2/7 kn, gamma_n 50 1/s, gamma_t gamma_n / 2, friction 0.5; 4 mm grains of 2500 kg/m^3)."""
    m_eff = 0.5 * 2500 * 4 / 3 * math.pi * 0.002 ** 3
    zeta = 50 / (2 * math.sqrt(2000 / m_eff))
    restitution = math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))
    return material_file(path, dimension=3, restitution=restitution)


@pytest.mark.parametrize("model", ["hooke/stiffness", "hertz"])
def test_liggghts_material_applies_to_its_linear_spring_dashpot_only(tmp_path, liggghts_hybrid, model):
    """Keyword material: its calibrations are of a linear spring-dashpot, which LIGGGHTS's
    hooke/stiffness is (its kn, kt, gamma_n, gamma_t, friction are checked against the
    calibration); with the Hertz model the material is refused, naming both laws."""
    path = liggghts_material(tmp_path / "m.toml")
    deck = edited_deck(tmp_path, lambda t: sub(r"youngs 1.0e5$", f"material {path}")(with_model(model, "1.0e-5")(t)))
    proc, elapsed = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "10", "-log", "none",
                           cwd=tmp_path)
    text = output(proc)
    if model == "hertz":
        assert proc.returncode != 0 and elapsed < STOP_WITHIN, text
        assert (f"ERROR: Fix hybrid/mpm: material {path} was calibrated for pair style gran/hooke/history (a linear "
                "spring-dashpot), the deck's contact model is gran model hertz") in text, text
        return
    assert proc.returncode == 0, text
    m = re.search(r"fix hybrid/mpm: material test_grains \(\S+\): Young's modulus (\S+) Pa, Poisson's ratio (\S+), "
                  r"friction angle (\S+) deg, mu_s ([0-9.e+-]+)", text)
    assert m, text
    assert [float(g) for g in m.groups()[1:]] == [0.2, 17.46, 0.3]


ADAPTIVE_DECK = REPO / "input_decks" / "hybrid" / "adaptive_3d.liggghts"
RUN_SUMMARY = re.compile(r"^fix hybrid/mpm: (steps|run of steps) (\d+)-(\d+): (\d+) rezones?: ", re.M)


def test_liggghts_timing_breakdown_rezone_summaries_and_fix_modify(tmp_path, liggghts_hybrid):
    """The LIGGGHTS host keeps the LAMMPS host's account of a run (coupler::DemRunLog): two coupled
    runs with adaptive zones on 2 ranks each end with the timing breakdown in LAMMPS's columns
    (sections adding up to the coupling's total, its own timers on the last line); thermo prints
    entries 30-33, positive, with the MPM wait and the rezones within the coupling's time and that
    within the run's loop time; the rezone log sums the rezones at thermo output, and fix_modify
    changes rezone_log between the runs (quiet: only the run's summary)."""
    text = ADAPTIVE_DECK.read_text()
    out = re.sub(r"^thermo_style .*$", "thermo_style    custom step atoms f_couple f_couple[30] f_couple[31] "
                 "f_couple[32] f_couple[33]", text, flags=re.M)
    assert out != text
    out += "\nfix_modify      couple rezone_log quiet depth 0.012\nrun             40\n"
    deck = tmp_path / "deck.in"
    deck.write_text(out)
    proc, _ = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "60", "-var", "rezone_log",
                     "summary", "-log", "log.lammps", timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, output(proc)
    log = (tmp_path / "log.lammps").read_text(errors="replace")
    # the breakdown at the end of each run
    blocks = timing_blocks(log)
    assert [b["exchanges"] for b in blocks] == [12, 8], log      # every 5 steps: 60 then 40 more
    assert blocks[0]["rezones"] >= 2 and blocks[1]["rezones"] >= 1, log    # the conversion and the oracle's
    for b in blocks:
        rows = b["rows"]
        assert list(rows) == TIMING_SECTIONS, rows
        total = rows["Coupling"]
        assert sum(r[1] for s, r in rows.items() if s != "Coupling") == pytest.approx(total[1], rel=1e-3, abs=1e-4)
        assert 0.0 < rows["MPM wait"][1] <= total[1] and rows["Rezone"][1] > 0.0, rows
        # LIGGGHTS times no fixes: the coupling is part of its Other (the loop less its timed sections)
        m = re.match(r"DEM side \(LIGGGHTS timer, avg\): Pair (\S+) Neigh (\S+) Comm (\S+) Other (\S+) s; "
                     r"coupling (\S+) s of (\S+) s wall \((\S+)%, part of Other\)$", b["dem"])
        assert m, b["dem"]
        pair, neigh, comm, other, coupling, wall, share = (float(g) for g in m.groups())
        assert pair > 0.0 and min(neigh, comm) >= 0.0, b["dem"]
        assert 0.0 < coupling <= other * (1 + 1e-3) and other <= wall, b["dem"]
        assert share == pytest.approx(total[4], abs=0.01) and 0.0 < share <= 100.0, b["dem"]
    # thermo entries 30-33 within each run's loop time
    loops = [float(t) for t in re.findall(r"^Loop time of (\S+) on 2 procs", log, flags=re.M)]
    tables = thermo_tables(liggghts_headers(log, out))
    assert len(tables) == len(loops) == 2, log
    coupling_before = 0.0
    for table, loop in zip(tables, loops):
        last = table[-1]
        coupling, wait, rezone, share = (last[f"f_couple[{k}]"] for k in (30, 31, 32, 33))
        assert 0.0 < wait and 0.0 < rezone and wait + rezone <= coupling, last
        assert coupling - coupling_before <= loop, (last, loop)    # entry 30 counts all runs
        assert 0.0 < share <= 100.0, last
        coupling_before = coupling
    # rezone log: summaries at thermo output in the first run (summary), only the run's in the second
    second = log.index("fix_modify      couple rezone_log quiet")
    first_kinds = [m[1] for m in RUN_SUMMARY.finditer(log[:second])]
    second_kinds = [m[1] for m in RUN_SUMMARY.finditer(log[second:])]
    assert "steps" in first_kinds and first_kinds[-1] == "run of steps", log
    assert second_kinds == ["run of steps"], log
    # the oracle's rezones print no lines of their own at either level (only the conversion's)
    assert len(re.findall(r"^fix hybrid/mpm: step \d+: \d+ grains became", log, flags=re.M)) == 1, log


def test_liggghts_fix_modify_refuses_a_bad_value_naming_it(tmp_path, liggghts_hybrid):
    deck = edited_deck(tmp_path, lambda t: t.replace("thermo          10",
                                                     "fix_modify      couple rezone_log loud\nthermo          10"))
    proc, elapsed = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "10", "-log", "none")
    text = output(proc)
    assert proc.returncode != 0 and elapsed < STOP_WITHIN, text
    assert ("ERROR: Illegal fix hybrid/mpm command: keyword 'rezone_log' must be full, summary or quiet, not "
            "'loud'") in text, text


def plate_stl(path: Path, z: float, lo: float = 0.001, hi: float = 0.159) -> Path:
    """An ASCII STL of a square plate at height z: two triangles."""
    tri = [((lo, lo, z), (hi, lo, z), (hi, hi, z)), ((lo, lo, z), (hi, hi, z), (lo, hi, z))]
    facets = "".join("facet normal 0 0 1\nouter loop\n" + "".join(f"vertex {x} {y} {zz}\n" for x, y, zz in t) +
                     "endloop\nendfacet\n" for t in tri)
    path.write_text(f"solid plate\n{facets}endsolid plate\n")
    return path


def with_mesh_wall(stl: Path):
    """The deck with a mesh wall (fix mesh/surface + fix wall/gran ... mesh) before the coupling."""
    def edit(text: str) -> str:
        return sub(r"^(fix\s+couple\s)", f"fix             plate all mesh/surface file {stl} type 1\n"
                   "fix             wall all wall/gran model hooke/stiffness tangential history mesh n_meshes 1 "
                   "meshes plate\n" + r"\1")(text)
    return edit


def test_liggghts_mesh_wall_is_a_boundary_of_the_zone_oracle(tmp_path, liggghts_hybrid):
    """A mesh wall through the middle of the adaptive 3D patch (a plate at z = 0.084, between two
    layers of grains that just touch it): the fix finds its triangles and the grid cells they pass
    through (one layer of 16 x 16 cells of 0.01 m), and the oracle keeps them discrete like the
    cells of discrete regions: the continuum is smaller than without the wall, with the same grains.
    (Without the fix knowing the wall, the dense grains on both sides of it would be continuum.)"""
    stl = plate_stl(tmp_path / "plate.stl", 0.084)
    base = ADAPTIVE_DECK.read_text()
    continuum = {}
    for name, text in (("without", base), ("with", with_mesh_wall(stl)(base))):
        d = tmp_path / name
        d.mkdir()
        (d / "deck.in").write_text(text)
        proc, _ = launch("--host", "liggghts", "-np", "2", "deck.in", "-var", "nsteps", "10", "-var", "rezone_log",
                         "full", "-log", "log.lammps", timeout=120, cwd=d)
        assert proc.returncode == 0, output(proc)
        log = (d / "log.lammps").read_text(errors="replace")
        said = re.findall(r"^fix hybrid/mpm: mesh walls \(fix mesh/surface (\S+)\): (\d+) triangles on (\d+) grid cells, "
                          r"kept discrete", log, flags=re.M)
        assert said == ([("plate", "2", "256")] if name == "with" else []), log
        # the conversion at step 1 is the oracle's first map (no continuum regions)
        first = re.search(r"^fix hybrid/mpm: step 1: .* grid cells in the box: (\d+) continuum, (\d+) hybrid", log,
                          flags=re.M)
        assert first, log
        continuum[name] = int(first.group(1))
    assert continuum["without"] > 0, continuum
    assert continuum["with"] < continuum["without"], continuum


def test_liggghts_mesh_wall_inside_continuum_regions_is_refused(tmp_path, liggghts_hybrid):
    """Fixed continuum regions cannot leave a mesh wall's grains discrete: a plate through the
    momentum deck's continuum core is an error naming the problem and both ways out."""
    deck = edited_deck(tmp_path, with_mesh_wall(plate_stl(tmp_path / "plate.stl", 0.0501, hi=0.099)))
    proc, elapsed = launch("--host", "liggghts", "-np", "2", str(deck), "-var", "nsteps", "10", "-log", "none",
                           cwd=tmp_path)
    text = output(proc)
    assert proc.returncode != 0 and elapsed < STOP_WITHIN, text
    assert re.search(r"ERROR: Fix hybrid/mpm: the continuum regions make \d+ grid cells that a mesh wall \(fix "
                     r"mesh/surface\) passes through continuum or hybrid", text), text
    assert "mpm_solver: error: LIGGGHTS stopped the coupled run" in text, text


INSERTION = """fix             pts all particletemplate/sphere 15485867 atom_type 1 density constant 2500 radius constant 0.002
fix             pdd all particledistribution/discrete 32452843 1 pts 1.0
region          ins block 0.084 0.098 0.02 0.08 0.02 0.08 units box
fix             ins {group} insert/pack seed 49979687 distributiontemplate pdd insert_every once overlapcheck yes &
                all_in yes particles_in_region 20 region ins
"""


@pytest.mark.parametrize("coupled, inserted", [("all", "all"), ("grains", "grains"), ("grains", "all")])
def test_liggghts_inserted_particles_join_the_coupled_group(tmp_path, liggghts_hybrid, coupled, inserted):
    """Particles fix insert/pack makes during a coupled run (20 spheres of 4 mm beside the
    momentum deck's cube, at rest, at the start of a second run) get the fix's per-atom data (weight 1, no support force) and
    join the coupling when the insertion fix's group is the coupled one: the total mass of grains
    plus points (f_couple[8]) grows by exactly their mass and the total momentum does not change.
    Inserted into another group they stay outside the coupling, and the fix says so."""
    def edit(text: str) -> str:
        if coupled != "all":
            text = sub(r"^(fix\s+couple) all ", rf"\1 {coupled} ")(text)
        text = sub(r"^(region\s+core .*)$", r"\1\ngroup           grains region patch")(text)
        # a first run converts the core; the insertion fix, defined after it, inserts at the next run's start
        return sub(r"^run\s+\$\{nsteps\}$", "run 10\n" + INSERTION.format(group=inserted) + "run 20")(text)
    deck = edited_deck(tmp_path, edit)
    proc, _ = launch("--host", "liggghts", "-np", "2", str(deck), "-log", "log.lammps", cwd=tmp_path)
    text = output(proc)
    assert proc.returncode == 0, text
    log = liggghts_headers((tmp_path / "log.lammps").read_text(errors="replace"), deck.read_text())
    first, last = thermo_tables(log)[0][-1], thermo_tables(log)[-1][-1]
    assert (first["Step"], last["Step"]) == (10, 30)
    assert last["Atoms"] == first["Atoms"] + 20, (first, last)    # inserted at step 11
    warned = ("WARNING: Fix hybrid/mpm: fix insert/pack ins inserts particles into group all, not into the coupled "
              "group grains: they will not be coupled nor counted in the fix's totals; give the insertion fix the "
              "group grains to couple them")
    joined = coupled == inserted or coupled == "all"
    assert (warned in text) != joined, text
    grain_mass = 2500 * 4 / 3 * math.pi * 0.002 ** 3
    added = 20 * grain_mass if joined else 0.0
    assert last["f_couple[8]"] == pytest.approx(first["f_couple[8]"] + added, rel=1e-12), (first, last)
    scale = first["f_couple[8]"] * 0.05
    for col in ("f_couple[9]", "f_couple[10]", "f_couple[11]"):
        assert abs(last[col] - first[col]) <= 1e-13 * scale, (col, first[col], last[col])
