"""Adaptive zones (fix hybrid/mpm keyword `adaptive`): the zone oracle moves cells between
discrete, hybrid and continuum during the run, and every move hands material between grains
and material points with exact mass, linear momentum and angular momentum.

Every rezone prints the totals of grains (carried mass, orbital plus spin angular momentum)
plus points (APIC angular momentum) just before and just after it; they are taken at the same
instant, so they differ only by what the handoff itself does.
"""
from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO
from hgtools.logs import ledger, ledger_closure, rezone_energy, thermo_rows, thermo_tables
from test_coupled_physics import LAUNCH, env, liggghts_headers, run_deck

DECKS = {"2d": REPO / "input_decks" / "hybrid" / "adaptive_2d.lmp",
         "3d": REPO / "input_decks" / "hybrid" / "adaptive_3d.lmp"}
REZONE = re.compile(r"step (\d+): (\d+) grains became (\d+) material points, (\d+) grains are hybrid "
                    r"\(weight [\d.]+\), (\d+) grains made from points; (\d+) cells moved")
TOTALS = re.compile(r"step (\d+): totals before/after the rezone:((?: \S+){14})")


LINE = re.compile(r"fix hybrid/mpm: step (\d+): (\d+) grains became (\d+) material points, (\d+) grains are hybrid "
                  r"\(weight [\d.]+\), (\d+) grains made from points; (\d+) cells moved; grid cells in the box: "
                  r"(\d+) continuum, (\d+) hybrid, (\d+) discrete; (\d+) cells gave their rest of material to nearby "
                  r"points, (\d+) kept it; carried mass / solid mass (\S+) to (\S+)")
SUMMARY = re.compile(r"fix hybrid/mpm: (steps|run of steps) (\d+)-(\d+): (\d+) rezones?: (\d+) grains became (\d+) "
                     r"material points, (\d+) grains made from points, (\d+) cells moved; (\d+) cells gave their rest "
                     r"of material to nearby points, (\d+) kept it; now (\d+) hybrid grains, zones (\d+) continuum, "
                     r"(\d+) hybrid, (\d+) discrete cells; carried mass / solid mass (\S+) to (\S+)")
# the fields both kinds of line have, in the order of LINE's groups after the step
SUMMED = ("deleted", "points", "made", "cells", "rests_moved", "rests_kept")
LAST = ("hybrid", "continuum_cells", "hybrid_cells", "discrete_cells")


def rezone_lines(log: str) -> list[dict]:
    """Every rezone's first line of a full log (keyword rezone_log full), as numbers."""
    return [dict(step=int(m[1]), deleted=int(m[2]), points=int(m[3]), hybrid=int(m[4]), made=int(m[5]),
                 cells=int(m[6]), continuum_cells=int(m[7]), hybrid_cells=int(m[8]), discrete_cells=int(m[9]),
                 rests_moved=int(m[10]), rests_kept=int(m[11]), lightest=float(m[12]), heaviest=float(m[13]))
            for m in LINE.finditer(log)]


def rezone_summaries(log: str) -> list[dict]:
    """The summary lines of the rezone log: kind 'steps' (since the last thermo output) or 'run of steps'."""
    return [dict(kind=m[1], first=int(m[2]), last=int(m[3]), rezones=int(m[4]), deleted=int(m[5]),
                 points=int(m[6]), made=int(m[7]), cells=int(m[8]), rests_moved=int(m[9]), rests_kept=int(m[10]),
                 hybrid=int(m[11]), continuum_cells=int(m[12]), hybrid_cells=int(m[13]), discrete_cells=int(m[14]),
                 lightest=float(m[15]), heaviest=float(m[16]))
            for m in SUMMARY.finditer(log)]


def rezones(log: str) -> tuple[list[dict], list[np.ndarray]]:
    """The rezone lines of a LAMMPS log: counts, and totals as 7 x 2 arrays (before, after) of
    mass, momentum x y z, angular momentum x y z."""
    counts = [dict(step=int(m[1]), grains_to_points=int(m[2]), points_made=int(m[3]), hybrid=int(m[4]),
                   grains_made=int(m[5]), cells=int(m[6])) for m in REZONE.finditer(log)]
    totals = [np.array(m[2].split(), dtype=float).reshape(7, 2) for m in TOTALS.finditer(log)]
    return counts, totals


@pytest.mark.parametrize("np_", [1, 2])
@pytest.mark.parametrize("dim,host", [("2d", "lammps"), ("3d", "lammps"), ("3d", "liggghts")])
def test_every_handoff_keeps_mass_momentum_and_angular_momentum(tmp_path, hybrid_programs, dim, host, np_):
    """A patch of grains with random velocities and no external force: the oracle makes its
    interior continuum at step 1, then (shear-rate criterion on) turns fast-shearing continuum
    back into grains and later into points again. Before and after each rezone the totals agree
    to round-off, in 2D and 3D, on 1 and 2 DEM ranks, with LAMMPS and (3D) LIGGGHTS as the DEM
    host (its twin deck adaptive_3d.liggghts); both directions of handoff happen."""
    nsteps = 200 if dim == "2d" else 100
    deck = DECKS[dim] if host == "lammps" else DECKS[dim].with_suffix(".liggghts")
    log = run_deck(tmp_path, deck, np_, "-var", "nsteps", str(nsteps), host=host)
    counts, totals = rezones(log)
    assert [c["step"] for c in counts] == [1] + list(range(21, nsteps, 20))
    assert len(totals) == len(counts)
    first = counts[0]
    assert first["grains_to_points"] > 0 and first["points_made"] > 0 and first["hybrid"] > 0
    later = counts[1:]
    assert sum(c["grains_made"] for c in later) > 100, later             # enrichment
    assert sum(c["grains_to_points"] + c["hybrid"] for c in later) > 100, later  # homogenisation
    rows = thermo_tables(log)[-1]
    mass = rows[0]["f_couple[8]"]
    # scales of what cancels: mass times the grains' speed (0.05 m/s), and times the box size
    box = 0.2 if dim == "2d" else 0.16
    scale = np.array([mass] + [mass * 0.05] * 3 + [mass * 0.05 * box] * 3)
    # round-off of sums over N bodies: a few N machine epsilons at worst
    tolerance = 4 * rows[0]["Atoms"] * np.finfo(float).eps
    for c, t in zip(counts, totals):
        change = np.abs(t[:, 1] - t[:, 0])
        assert (change <= tolerance * scale).all(), (c, change / scale)
    # mass over the whole run, and the atom count follows the handoffs
    for r in rows[1:]:
        assert r["f_couple[8]"] == pytest.approx(mass, rel=tolerance)
    assert rows[-1]["Atoms"] != rows[1]["Atoms"]
    # the energy ledger closes through every handoff and exchange. With no gravity the energy is
    # kinetic: the grains' collisions and the agreements dissipate it. (Rezones that hand rests
    # to the points of nearby cells add energy here: docs/fix_hybrid_mpm.md, "Energy ledger".)
    end = assert_ledger_closes(rows)
    assert end["DEM steps"] < 0, end
    assert end["agreement (grains)"] + end["agreement (continuum)"] < 0, end
    assert end["rezones (grains)"] != 0 and end["rezones (continuum)"] != 0, end
    # the grains' side of the rezones, split: grains made from points bring their kinetic energy,
    # removed ones take theirs, no potential energy without gravity
    split = assert_grain_rezone_split(log, end)
    assert split["made"]["kinetic"] > 0 and split["removed"]["kinetic"] < 0, split
    assert all(split[term]["potential"] == 0 for term in ACTIONS + MECHANISMS), split
    # the handoffs go both ways: cells turned continuum took grains, cells turned discrete made them
    assert split["homogenisation"]["kinetic"] < 0 < split["enrichment"]["kinetic"], split


def test_grid_chosen_from_the_grains_makes_coarse_points(tmp_path, hybrid_programs):
    """Without `cell` the fix chooses the grid from the grains (docs/fix_hybrid_mpm.md, "Grid from
    the grains"): with one point per cell and axis, cells of 3 grain diameters, so that a point
    stands for about 9 grains, and the oracle's depth and band from that cell. The conversion
    makes one point per continuum or hybrid cell, from the 9 lattice grains of each, and the
    handoffs keep their totals as with a given cell."""
    log = run_deck(tmp_path, DECKS["2d"], 1, "-var", "nsteps", "60", "-var", "cell", "0", "-var", "ppc", "1")
    assert ("fix hybrid/mpm: cell 0.006 = 3 mean grain diameters (chosen from the grains), 1^2 points per cell: "
            "a point made from grains carries 9.4 grains at packing 0.82") in log, log
    first = rezone_lines(log)[0]
    assert first["continuum_cells"] > 0 and first["hybrid_cells"] > 0, first
    # one point per cell that holds material points (continuum and hybrid cells)
    assert first["points"] == first["continuum_cells"] + first["hybrid_cells"], first
    # a continuum cell's 9 grains become its point; a hybrid cell's grains stay (weight 0.5)
    assert first["deleted"] == 9 * first["continuum_cells"], first
    for c, t in zip(*rezones(log)):
        assert np.abs(t[:, 1] - t[:, 0]).max() <= 1e-12 * np.abs(t).max(), c


def test_rezone_log_sums_the_rezones_at_thermo_output(tmp_path, hybrid_programs):
    """The rezone log (keyword rezone_log) of the 2D patch, 120 steps on 1 rank (oracle every 20
    steps, thermo every 10; cells shearing faster than 2 1/s forced discrete, so that grains turn
    into points again within the run). Full: every rezone prints its lines, and at each thermo output that
    follows rezones a summary adds them up: its counts are the sums of the rezone lines of its
    steps, its hybrid grains and zones those of the last (and the thermo vector's zones, entries
    16-18, at its step), its carried-mass extremes those over its rezones; the run's summary
    covers all of them. The default log of the same run prints the lines of the conversion at
    step 1 only, and summaries of the same rezones; quiet only the run's summary."""
    nsteps = 120
    logs = {}
    for level in ("full", "summary", "quiet"):
        (tmp_path / level).mkdir()
        logs[level] = run_deck(tmp_path / level, DECKS["2d"], 1, "-var", "nsteps", str(nsteps),
                               "-var", "rezone_log", level, "-var", "shear", "2")
    lines, summaries = rezone_lines(logs["full"]), rezone_summaries(logs["full"])
    oracle_steps = [1] + list(range(21, nsteps, 20))
    assert [r["step"] for r in lines] == oracle_steps
    assert len(TOTALS.findall(logs["full"])) == len(lines)
    intervals = [s for s in summaries if s["kind"] == "steps"]
    runs = [s for s in summaries if s["kind"] == "run of steps"]
    assert len(runs) == 1 and (runs[0]["first"], runs[0]["last"]) == (1, nsteps)
    # one summary per thermo interval (thermo every 10) that holds a rezone
    assert [(s["first"], s["last"]) for s in intervals] == [(1, 10)] + [(k, k + 9) for k in oracle_steps[1:]]
    thermo = {int(r["Step"]): r for r in thermo_rows(logs["full"])}
    for s in intervals + runs:
        covered = [r for r in lines if s["first"] <= r["step"] <= s["last"]]
        assert s["rezones"] == len(covered) > 0, s
        for key in SUMMED:
            assert s[key] == sum(r[key] for r in covered), (key, s)
        for key in LAST:
            assert s[key] == covered[-1][key], (key, s)
        assert s["lightest"] == min(r["lightest"] for r in covered)
        assert s["heaviest"] == max(r["heaviest"] for r in covered)
        row = thermo[s["last"]]
        assert (row["f_couple[16]"], row["f_couple[17]"], row["f_couple[18]"]) == \
            (s["continuum_cells"], s["hybrid_cells"], s["discrete_cells"]), s
    assert sum(s["rezones"] for s in intervals) == runs[0]["rezones"] == len(oracle_steps)
    assert any(s["made"] > 0 for s in intervals) and any(s["deleted"] > 0 for s in intervals[1:])

    # the default: the conversion's two lines, then only summaries, of the same rezones
    default = logs["summary"]
    assert [r["step"] for r in rezone_lines(default)] == [1]
    assert [m[0] for m in TOTALS.findall(default)] == ["1"]
    counted = [(s["kind"], s["first"], s["last"], s["rezones"]) for s in rezone_summaries(default)]
    assert counted == [(s["kind"], s["first"], s["last"], s["rezones"]) for s in summaries]
    # quiet: the run's summary only
    assert rezone_lines(logs["quiet"]) == [] and TOTALS.findall(logs["quiet"]) == []
    assert [(s["kind"], s["rezones"]) for s in rezone_summaries(logs["quiet"])] == [("run of steps", len(oracle_steps))]


ACTIONS = ("made", "removed", "corrected")                  # what a rezone did to the grains
MECHANISMS = ("enrichment", "homogenisation", "repair")     # by the cells' zone change


def assert_grain_rezone_split(log: str, end: dict) -> dict:
    """The fix's end-of-run lines split the grains' side of the rezones into grains made, removed
    and corrected (kinetic and potential), and again by the cells' zone change (enrichment,
    homogenisation, repair); each split sums to the line's total; over the runs of the log they sum to the ledger's
    entry 27 at its end (`end`, the last thermo row's ledger), to round-off of the energy scale.
    Returns the split summed over the runs."""
    runs = rezone_energy(log, "grains")
    assert runs, "no line of the rezones' energy on the grains in the log"
    total = {term: {part: sum(r[term][part] for r in runs) for part in ("total", "kinetic", "potential")}
             for term in ACTIONS + MECHANISMS}
    for r in runs:    # each line's terms add up to its sum (6 digits printed) and to their parts, by
        for split in (ACTIONS, MECHANISMS):    # what they did to the grains and by the cells' zone change
            terms = [r[t] for t in split]
            scale = max(abs(t["total"]) for t in terms) + 1e-300
            assert abs(sum(t["total"] for t in terms) - r["all"]) <= 2e-5 * scale, (split, r)
            for t in terms:
                assert t["total"] == pytest.approx(t["kinetic"] + t["potential"], abs=2e-5 * scale), r
    # 6 significant digits a term: the sum matches the ledger to their precision
    scale = max(abs(total[t]["total"]) for t in total)
    assert sum(r["all"] for r in runs) == pytest.approx(end["rezones (grains)"], abs=2e-5 * scale), (runs, end)
    assert scale > 0
    return total


def assert_ledger_closes(rows: list[dict]) -> dict:
    """Every row: grains + continuum = their sum (as printed), and the total's change since the
    start is the sum of what each mechanism changed, to round-off of the largest figure
    involved. Returns the last row's ledger."""
    for r in rows:
        e = ledger(r)
        assert e["total"] == pytest.approx(e["grains"] + e["continuum"], rel=1e-7, abs=1e-7 * abs(ledger(rows[0])["total"]))
    assert ledger_closure(rows) <= 1e-12, [ledger(r) for r in rows[-3:]]
    return ledger(rows[-1])


CYCLE_DECK = REPO / "input_decks" / "hybrid" / "handoff_cycle_2d.lmp"


def test_handoff_cycle_in_a_bed_at_rest_releases_little_energy(tmp_path, hybrid_programs):
    """A settled 2D bed (736 polydisperse disks): the oracle makes its interior continuum, then
    (fix_modify depth beyond the bed) everything returns to grains cut from the packing
    template. The new packing is not the old one and its contacts carry no load yet, so the
    bed above sags into it and bounces, weakly damped. The kinetic energy this releases
    (grains plus points) stays below 2 % of the bed's potential energy m g y_cm, the centre of
    mass ends less than 5 % lower, and the motion dies away.
    Measured: KE peak 1.5 % of m g y_cm, centre of mass 3.8 % lower (mean of the last third)."""
    log = run_deck(tmp_path, CYCLE_DECK, 2)
    counts, totals = rezones(log)
    made = sum(c["grains_made"] for c in counts)
    assert counts[0]["points_made"] > 200 and made > 100
    lines = log.splitlines()
    rows = []
    for start in [i for i, ln in enumerate(lines) if ln.split()[:2] == ["Step", "Atoms"] and "f_couple[3]" in ln]:
        header = lines[start].split()
        for ln in lines[start + 1:]:
            if ln.startswith("Loop time"):
                break
            parts = ln.split()
            if len(parts) == len(header) and re.match(r"^\d", parts[0]):
                rows.append(dict(zip(header, map(float, parts))))
    pe0 = rows[0]["v_pe"]                       # settled, all grains
    ke0 = rows[0]["c_ke"]
    assert ke0 < 1e-5 * pe0
    assert max(r["f_couple[3]"] for r in rows) > 200          # the interior was continuum
    last = rows[-1]
    assert last["f_couple[3]"] == 0 and last["f_couple[16]"] == 0 and last["f_couple[17]"] == 0  # all grains again
    assert last["f_couple[8]"] == pytest.approx(rows[0]["f_couple[8]"], rel=1e-12)              # mass exact
    ke = np.array([r["c_ke"] + r["f_couple[15]"] for r in rows])
    pe_end = np.mean([r["v_pe"] for r in rows[-len(rows) // 3:]])
    tail = ke[-len(ke) // 4:].max()
    print(f"handoff cycle: KE peak {ke.max() / pe0:.2%} of m g y_cm, centre of mass {1 - pe_end / pe0:.2%} "
          f"lower, KE in the last quarter at most {tail / ke.max():.1%} of the peak")
    assert ke.max() < 0.02 * pe0
    assert pe_end > 0.95 * pe0
    assert tail < 0.1 * ke.max()


# ---- column collapse with adaptive zones (input_decks/column_collapse/dem_2d.lmp, hybrid 2) -----

def grid_cells(x: np.ndarray, origin: np.ndarray, dx: float) -> np.ndarray:
    """The integer coordinates of the grid cells holding the points `x` (2D)."""
    return np.floor((x[:, :2] - origin[:2]) / dx).astype(int)


def material_distance(grains: dict, points: dict, origin: np.ndarray, dx: float, container_lo: np.ndarray,
                      surface_packing: float, cells: np.ndarray) -> np.ndarray:
    """Distance of the centres of `cells` (integer coordinates of the MPM grid's cells, from its
    `origin`) to the nearest centre of a cell outside the material, minus dx/2, as the oracle
    measures it: outside = packing fraction (grain area in the cell of its centre, over dx^2)
    below surface_packing and no material point, or a centre outside the container (beyond
    container_lo). Brute force."""
    gc, pc = grid_cells(grains["position"], origin, dx), grid_cells(points["position"], origin, dx)
    n = np.concatenate([gc, pc, cells]).max(axis=0) + 3
    area = np.zeros(n)
    ok = (gc >= 0).all(axis=1)
    np.add.at(area, (gc[ok, 0], gc[ok, 1]), np.pi * grains["radius"][ok] ** 2)
    material = area / dx ** 2 >= surface_packing
    material[pc[:, 0], pc[:, 1]] = True
    centre = origin[:2, None, None] + dx * (np.indices(n) + 0.5)
    material &= (centre >= np.asarray(container_lo)[:, None, None]).all(axis=0)
    outside = np.argwhere(~material)
    d = np.sqrt(((cells[:, None, :] - outside[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
    return (d - 0.5) * dx


def test_discrete_zone_follows_the_free_surface_of_a_collapsing_column(tmp_path, hybrid_programs):
    """The 2D column collapse (a = 2, L0 = 25 d, about 1300 disks) from a settled column, coupled
    with adaptive zones only (no continuum region on the fix line): at the start the oracle
    makes the column's interior continuum; as the column collapses and spreads, the continuum
    shrinks and moves with the material. At the end the zone map differs from the start; in the
    last frame that still holds continuum (with the calibrated material the deposit at rest is
    thinner than 3 cells from its surface and the floor, so the continuum may be gone by then)
    its top has come down with the free surface, and no continuum point lies closer to the free
    surface (or the back wall and floor) than the depth L = 2 cells (hdepth; the continuum
    starts at L + h = 3 cells): the grains along the free surface are discrete."""
    import os
    from conftest import BUILD
    import mpm_results
    from dem_collapse import run
    os.environ.setdefault("HYBRID_BUILD_DIR", str(BUILD))
    os.environ["OMP_NUM_THREADS"] = "1"
    width, d = 0.05, 0.002
    dx = width / 10
    res = run(aspect=2.0, width=width, d=d, np_=2, out=tmp_path / "hybrid", extra_vars={"mu": 0.5, "e": 0.5},
              hybrid_vars={"hybrid": 2, "hdepth": 2 * dx, "houtev": 200, "hlog": "full"}, timeout=1200)
    print(res.summary())
    log = (tmp_path / "hybrid" / "log.lammps").read_text()
    zones = [tuple(map(int, m)) for m in
             re.findall(r"grid cells in the box: (\d+) continuum, (\d+) hybrid, (\d+) discrete", log)]
    assert len(zones) > 50
    assert zones[0][0] > 10 and zones[-1] != zones[0]
    moved = sum(c["cells"] for c in rezones(log)[0][1:])
    assert moved > 50
    frames = mpm_results.Run(tmp_path / "hybrid" / "frames")
    assert len(frames) > 10
    first = frames.frame(0)
    with_continuum = [k for k in range(len(frames)) if (frames.frame(k)["zone"] == 2).any()]
    k = with_continuum[-1]
    last = frames.frame(k)
    cont0, cont1 = first["zone"] == 2, last["zone"] == 2
    assert cont0.sum() > 50 and cont1.sum() > 0
    # the continuum came down with the free surface (the column's height halves)
    assert last["position"][cont1, 1].max() < first["position"][cont0, 1].max() - 3 * dx
    grains = mpm_results.read_grains(tmp_path / "hybrid" / "frames", k)
    # the cells of the MPM grid (laid from the grains: its origin need not be the container's)
    assert frames.grid is not None and frames.grid["dx"] == pytest.approx(dx)
    origin = frames.grid["origin"]
    cells = np.unique(grid_cells(last["position"][cont1], origin, dx), axis=0)
    dist = material_distance(grains, last, origin, dx, np.zeros(2), 0.3, cells)  # back wall x = 0, floor y = 0
    print(f"continuum cells in frame {k} of {len(frames)}: {len(cells)}, nearest to the surface or walls "
          f"{dist.min() / dx:.2f} cells; "
          f"zones first {zones[0]}, last {zones[-1]}; runout {res.runout:.2f}")
    assert dist.min() >= 2 * dx
    # the energy ledger closes over the collapse (the deck prints it at every thermo row); the
    # DEM's contacts dissipate most of the released energy, and the coupling never adds energy
    table = thermo_rows(tmp_path / "hybrid" / "log.lammps", require="f_couple[29]")
    end = assert_ledger_closes(table)
    released = ledger(table[0])["total"] - end["total"]
    assert released > 0
    # the grains' side of its rezones, split: with gravity the made and removed grains carry
    # potential energy too
    split = assert_grain_rezone_split(log, end)
    assert split["made"]["potential"] != 0 and split["removed"]["potential"] != 0, split
    assert -end["DEM steps"] > 0.3 * released, end
    assert end["agreement (grains)"] + end["agreement (continuum)"] < 0, end


@pytest.mark.parametrize("host, deck", [("lammps", DECKS["3d"]),
                                        ("liggghts", REPO / "input_decks" / "hybrid" / "adaptive_3d.liggghts")])
def test_discrete_region_that_touches_no_cell_is_refused(tmp_path, hybrid_programs, host, deck):
    """A `discrete` region keeps every cell it touches (coupler::cells_touched samples 3^3 points of
    each cell, since a region narrower than a cell may hold no cell centre: a 3D silo's outlet
    cylinder about an axis on a node line kept nothing discrete, and with the floor touched its
    continuum covered the orifice and nothing flowed out). One narrower than the samples' spacing
    keeps nothing and is refused at the start with the fix: here a cylinder of 0.1 cell about
    the node line x = z = 0.08 (cells of 0.01 from 0); 0.3 cell runs."""
    def run(radius):
        text = deck.read_text().replace(
            "fix             couple all hybrid/mpm",
            f"region          keep cylinder y 0.08 0.08 {radius} INF INF units box\n"
            "fix             couple all hybrid/mpm discrete keep", 1)
        assert "discrete keep" in text
        variant = tmp_path / f"r{radius}" / deck.name
        variant.parent.mkdir()
        variant.write_text(text)
        launch = [sys.executable, str(LAUNCH), "--host", host, "-np", "1", str(variant),
                  "-log", str(variant.parent / "log.txt"), "-var", "nsteps", "20"]
        return subprocess.run(launch, capture_output=True, text=True, errors="replace", timeout=120, env=env(),
                              cwd=variant.parent)

    refused = run(0.001)
    assert refused.returncode != 0
    assert ("discrete region 'keep' touches no grid cell of the box (cell 0.01), so it keeps nothing discrete: "
            "make the region span at least a third of a cell, or the cell smaller") in refused.stdout + refused.stderr
    ran = run(0.003)
    assert ran.returncode == 0, ran.stdout[-3000:] + ran.stderr[-3000:]


GUARD_STOP = re.compile(r"the coupling made (\S+) J \(J/m in 2D\) of energy between t = (\S+) s and t = (\S+) s, "
                        r"(\S+) % of the scene's energy scale (\S+) J")


@pytest.mark.parametrize("host, deck", [("lammps", DECKS["2d"]),
                                        ("liggghts", REPO / "input_decks" / "hybrid" / "adaptive_3d.liggghts")])
def test_energy_guard_stops_a_run_whose_coupling_made_more_than_its_limit(tmp_path, hybrid_programs, host, deck):
    """The energy guard (keyword energy_guard, coupler::EnergyGuard): the gravity-free patch run
    unguarded shows how far the sum of ledger entries 23-28 (the continuum's steps, the agreements,
    the support force, the rezones) rises above its lowest, over the largest energy seen (the scale without
    gravity). With half that share as the limit the same run stops with the error that names the
    energy made above the limit, and the MPM process stops with it. The fix's margin (f_couple[36],
    the largest share the guard saw) is the smallest limit the run passes."""
    def run(limit):
        out = tmp_path / f"guard{limit:.6g}"
        out.mkdir()
        log = out / "log.txt"
        proc = subprocess.run([sys.executable, str(LAUNCH), "--host", host, "-np", "1", str(deck), "-log", str(log),
                               "-var", "nsteps", "100", "-var", "guard", f"{limit:.6g}"],
                              capture_output=True, text=True, errors="replace", timeout=120, env=env(), cwd=out)
        text = log.read_text(errors="replace") if log.exists() else ""
        return proc, liggghts_headers(text, deck.read_text()) if host == "liggghts" else text

    free, log = run(0)
    assert free.returncode == 0, free.stdout + free.stderr
    rows = thermo_tables(log)[-1]
    made = [sum(r[f"f_couple[{k}]"] for k in range(23, 29)) for r in rows]
    scale = max(abs(r["f_couple[19]"]) for r in rows)
    rise = max(m - min(made[:i + 1]) for i, m in enumerate(made))
    assert rise > 1e-6 * scale, (rise, scale)    # the patch's coupling does make some energy
    share = rise / scale
    # the fix's own margin (f_couple[36]) never falls and is of the order of what the rows show (not
    # equal to it: the guard also looks at every rezone, between the rows, with its scale as of then)
    margin = [r["f_couple[36]"] for r in rows]
    assert all(b >= a for a, b in zip(margin, margin[1:])), margin
    assert margin[-1] > share / 2, (margin[-1], share)

    stopped, _ = run(share / 2)
    out = stopped.stdout + stopped.stderr
    assert stopped.returncode != 0, out
    m = GUARD_STOP.search(out)
    assert m, out
    reported, since, until, percent, reported_scale = (float(g) for g in m.groups())
    assert reported > share / 2 * reported_scale, m.group(0)
    assert percent == pytest.approx(100 * reported / reported_scale, rel=6e-3)    # printed to 3 digits
    assert since < until
    assert "energy_guard 0 lets the run go on" in out
    assert "stopped the coupled run" in out, out    # the MPM process stopped with it

    # the margin is the smallest limit the run passes: just above it the run goes through, just below it stops
    through, _ = run(1.01 * margin[-1])
    assert through.returncode == 0, through.stdout + through.stderr
    below, _ = run(0.99 * margin[-1])
    assert below.returncode != 0 and GUARD_STOP.search(below.stdout + below.stderr), below.stdout + below.stderr

