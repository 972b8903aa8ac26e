"""tools/hgtools: the one runner, log reader and settled-state cache the scene drivers share."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from hgtools import bed, impact, laws, logs
from hgtools.cache import Settled
from hgtools.runner import TOOLS, Forms, RunFailed, command, run_deck

LOG = """LAMMPS (7 Jan 2022)
Step Time KinEng
       0            0            1
     100          0.1          0.5
WARNING: 3 atoms lost (src/thermo.cpp:444)
Loop time of 1.5 on 2 procs for 100 steps with 10 atoms
label           collapse_stage
Step Time KinEng f_couple[8]
     100          0.1          0.5            2
     200          0.2         0.25            2
Loop time of 2.5 on 2 procs for 100 steps with 10 atoms
DEM3D contact: kn = 1000 N/m, kt = 285.7 N/m, gamma_n = 5 1/s, gamma_t = 2.5 1/s, gamma_n(wall) = 7 1/s, gamma_t(wall) = 3.5 1/s
DEM3D timestep: tc = 1e-4 s, dt = 5e-6 s, rest KE/grain < 1e-9 J
"""


def test_thermo_tables_rows_and_loops():
    tables = logs.thermo_tables(LOG)
    assert [len(t) for t in tables] == [2, 2]            # the warning line is no row
    rows = logs.thermo_rows(LOG)
    assert [r["Step"] for r in rows] == [0, 100, 200]    # step 100, printed twice, counts once
    assert [r["Step"] for r in logs.thermo_rows(LOG, require="f_couple[8]")] == [100, 200]
    assert logs.loops(LOG) == (200, 4.0)
    assert logs.loops(LOG, after="label           collapse_stage") == (100, 2.5)
    params = logs.contact_params(LOG, "DEM3D")
    assert params["gamma_n(wall)"] == 7 and params["kt"] == 285.7 and params["dt"] == 5e-6
    with pytest.raises(RuntimeError, match="not in the log"):
        logs.number(r"^IMPACT end: (\S+)", LOG)


def test_command_lines_of_the_three_codes(tmp_path):
    deck, log = tmp_path / "deck.lmp", tmp_path / "log.txt"
    one = command("lammps", deck, {"out": tmp_path, "seed": 3}, log, exe="lmp")
    assert one == ["lmp", "-in", str(deck), "-log", str(log), "-screen", "none", "-var", "out", str(tmp_path),
                   "-var", "seed", "3"]
    two = command("liggghts", deck, {}, log, np_=2, exe="liggghts")
    assert two[:3] == [str(TOOLS / "mpirun.sh"), "-np", "2"] and two[-1] == "-nocite"
    hybrid = command("hybrid", deck, {"a": 1}, log, np_=2)
    assert hybrid[1:5] == [str(TOOLS / "hybrid_launch.py"), "-np", "2", str(deck)]
    forms = Forms("plough")
    assert forms.deck("liggghts").name == "liggghts_3d.in" and forms.deck("hybrid").name == "dem_3d.lmp"
    assert forms.variables("hybrid", {"d": 1}, {"hybrid": 2}) == {"d": 1, "hybrid": 2, "hdeck": forms.hybrid_deck()}
    assert forms.variables("lammps", {"d": 1}, {"hcell": 2}) == {"d": 1}
    # the LIGGGHTS-hosted hybrid: the LIGGGHTS deck with its own include, through hybrid_launch.py --host liggghts
    hybrid_liggghts = command("hybrid_liggghts", deck, {}, log, np_=2)
    assert hybrid_liggghts[1:6] == [str(TOOLS / "hybrid_launch.py"), "--host", "liggghts", "-np", "2"]
    silo = Forms("silo", hybrid_liggghts="hybrid_3d.liggghts")
    assert silo.deck("hybrid_liggghts").name == "liggghts_3d.in"
    assert silo.variables("hybrid_liggghts", {"d": 1}) == {"d": 1, "hybrid": 1,
                                                            "hdeck": silo.hybrid_deck("hybrid_liggghts")}
    assert silo.hybrid_deck("hybrid_liggghts").is_file()
    with pytest.raises(ValueError, match="has no hybrid_liggghts twin"):
        forms.variables("hybrid_liggghts", {})


def test_a_failed_run_names_the_code_the_stage_and_the_log_tail(tmp_path, lmp):
    deck = tmp_path / "bad.lmp"
    deck.write_text("units si\nnot_a_command 1\n")
    done = run_deck("lammps", deck, {}, tmp_path / "log.txt", exe=lmp, timeout=60)
    with pytest.raises(RunFailed, match=r"(?s)lammps failed to prepare the test \(1\).*not_a_command"):
        done.check("to prepare the test")


def test_cache_keys_stay_those_of_the_existing_entries(tmp_path):
    """The shared cache is keyed as before the runner existed, so every clone's settled states stay valid."""
    deck = tmp_path / "deck.lmp"
    deck.write_bytes(b"deck")
    params = dict(a=2.0, w=0.1, d=0.002, seed=12345)
    entry = Settled.entry("dem_column", "a2_w0.1_d0.002_s12345", params, (deck,), "settled.restart", tmp_path)
    key = hashlib.sha1(json.dumps(params, sort_keys=True).encode()).hexdigest()[:10]
    assert entry.path == (tmp_path / "dem_column" / f"a2_w0.1_d0.002_s12345_{key}_{hashlib.sha1(b'deck').hexdigest()[:10]}"
                          / "settled.restart")
    assert not entry.cached()
    state = tmp_path / "settled.restart"
    state.write_text("state")
    entry.store(state, {"grains": 5})
    assert entry.cached(with_info=True) and entry.info() == {"grains": 5} and entry.path.read_text() == "state"


def test_cache_key_of_a_staged_deck_ignores_its_later_stages(tmp_path):
    """A (deck, marker) source keys the state by the part before the marker's line: editing the
    stages that run from the cached state keeps it; editing the preparation does not; a deck
    without the marker is refused rather than keyed by all of it."""
    deck = tmp_path / "deck.lmp"
    params = dict(a=2.0)
    marker = "label           later"

    def key(text):
        deck.write_text(text)
        return Settled.entry("k", "l", params, ((deck, marker),), "s", tmp_path).path.parent.name

    base = key("prep 1\nlabel           later\ncollapse 1\n")
    assert key("prep 1\nlabel           later\ncollapse 2\n") == base
    assert key("prep 2\nlabel           later\ncollapse 1\n") != base
    assert base.endswith(hashlib.sha1(b"prep 1\n").hexdigest()[:10])
    with pytest.raises(ValueError, match="no line holding"):
        key("prep 1\ncollapse 1\n")


def test_katsuragi_durian_fit_recovers_k_and_d1():
    mp, k, d1 = 0.005, 400.0, 0.01
    z = np.linspace(1e-4, 0.02, 400)
    v = 4.0 * np.exp(-z / 0.008)                      # v^2 not linear in z: the two terms are told apart
    force = mp * laws.G + k * z + mp * v ** 2 / d1
    fit = laws.katsuragi_durian_fit(z, v, force, mp, 0.002)
    assert fit["k"] == pytest.approx(k, rel=1e-9) and fit["d1"] == pytest.approx(d1, rel=1e-9)
    assert fit["r2"] == pytest.approx(1.0) and len(fit["bins"]) == 20
    assert np.isnan(laws.katsuragi_durian_fit(z[:10], v[:10], force[:10], mp, 0.002)["k"])   # too few records


def test_published_laws():
    rho_p, rho_b, dp, h, mu = 2500.0, 1500.0, 0.016, 1.3, 0.5
    dep = laws.uehara_depth(rho_p, rho_b, dp, h, mu)
    assert dep == pytest.approx(0.14 / mu * (rho_p / rho_b) ** 0.5 * dp ** (2 / 3) * (h + dep) ** (1 / 3), rel=1e-12)
    assert laws.rankine_drag(1500.0, 0.01, 30.0) == pytest.approx(0.5 * 3.0 * 1500.0 * laws.G * 1e-4)   # K_p(30) = 3
    assert laws.beverloo_3d(1500.0, 0.013, 0.002) == pytest.approx(0.58 * 1500.0 * laws.G ** 0.5 * 0.01 ** 2.5)
    assert laws.beverloo_2d(1500.0, 0.013, 0.002) == pytest.approx(np.pi / 4 * 1500.0 * laws.G ** 0.5 * 0.01 ** 1.5)
    assert laws.beverloo_3d(1500.0, 0.002, 0.002) == 0.0                            # hole narrower than 1.5 d


def test_floor_hole_surface_and_packing_of_a_lattice():
    d = 0.002
    floor, s, inscribed = bed.floor_with_hole(0.03, 0.012, d)
    assert s <= 1.2 * d and inscribed >= 0.012
    dist = np.hypot(floor[:, 0] - 0.015, floor[:, 1] - 0.015)
    assert dist.min() - 0.5 * d == pytest.approx(0.5 * inscribed)
    # a simple cubic lattice of spheres, spacing a, radius r: phi = 4/3 pi r^3 / a^3, surface = top layer + r
    a, r, n, layers = 0.002, 0.0009, 30, 12
    c = (np.arange(n) + 0.5) * a
    X, Y, Z = np.meshgrid(c, c, (np.arange(layers) + 0.5) * a, indexing="ij")
    dump = dict(x=X.ravel(), y=Y.ravel(), z=Z.ravel(), radius=np.full(X.size, r), type=np.ones(X.size))
    phi = 4 / 3 * np.pi * r ** 3 / a ** 3
    surface = bed.surface_near_axis(dump, n * a, d, 0.01)
    assert surface == pytest.approx((layers - 0.5) * a + r)
    assert bed.box_packing(dump, n * a, d, surface) == pytest.approx(phi, rel=0.1)
    slab = dict(x=X.ravel(), y=Z.ravel(), z=Y.ravel(), radius=np.full(X.size, r), type=np.ones(X.size))
    state = bed.slab_bed(slab, layers * a, n * a, d, n * a)
    assert state["surface"] == pytest.approx((layers - 0.5) * a + r) and state["packing"] == pytest.approx(phi, rel=0.1)


def test_projectile_record_contact_stop_and_energy():
    mp, dp, surface = 0.01, 0.012, 0.03
    t = np.linspace(0.0, 0.02, 201)
    vz = np.where(t < 0.005, -4.0, -4.0 * np.clip(1 - (t - 0.005) / 0.01, 0.0, 1.0))   # touches at 5 ms, stops at 15
    zp = surface + 0.5 * dp + 0.002 - np.concatenate([[0.0], np.cumsum(-vz[:-1] * np.diff(t))])
    fz = np.where(t < 0.005, -mp * laws.G, 3.0)                                            # the bed pushes from 5 ms
    rec = np.column_stack([t, zp, vz, fz, 0.5 * mp * vz ** 2, np.zeros_like(t)])
    m = impact.projectile_record(rec, surface, dp, mp, 0.002, vstop=0.04)
    assert m["launch_gap"] == pytest.approx(0.002)
    assert 0.0099 < m["stop_time"] < 0.0101
    assert m["peak_decel"] == pytest.approx((3.0 + mp * laws.G) / mp)
    assert m["ke0"] == pytest.approx(0.08) and m["mobile_energy_gain"] == 0.0
    assert m["max_depth"] == pytest.approx(zp[0] - zp.min() - 0.002)


def test_hybrid_totals_from_the_log():
    text = ("HYBRID mass 2.0 points 10 cells continuum 3 hybrid 4\nHYBRID mass 2.02 points 12 cells continuum 5 hybrid 1\n"
            "Step f_couple[3] f_couple[8] f_couple[16] f_couple[17]\n 0 5 1.0 2 3\n 10 7 1.01 4 1\n")
    balance, points, cells = logs.hybrid_mass_lines(text)
    assert balance == pytest.approx(0.01) and points == 12 and cells == 7
    assert np.isnan(logs.hybrid_mass_lines("nothing")[0])
    totals = logs.hybrid_totals(text)
    assert totals["mass_drift"] == pytest.approx(0.01) and totals["points_max"] == 7
    assert totals["continuum_cells_max"] == 4 and totals["hybrid_cells_max"] == 3


def test_a_rewritten_report_keeps_its_notes(tmp_path):
    """A bench rewrites its report's tables and keeps what a person wrote below the marker."""
    from hgtools.report import NOTES_MARKER, write_report
    path = tmp_path / "bench.md"
    assert write_report(path, "# Table\n\n| a |\n| 1 |\n") == ""
    assert path.read_text().endswith(NOTES_MARKER + "\n")
    path.write_text(path.read_text() + "\nThe row says 1.\n")
    assert write_report(path, "# Table\n\n| a |\n| 2 |") == "The row says 1.\n"
    text = path.read_text()
    assert "| 2 |" in text and "| 1 |" not in text and text.endswith(NOTES_MARKER + "\n\nThe row says 1.\n")
    write_report(path, "# Table\n\n| a |\n| 2 |")
    assert path.read_text() == text    # rewriting is idempotent


def test_discharge_record_gives_the_grain_rate_and_the_mass_each_grain_carried(tmp_path):
    """hgtools.discharge.measure fits the grains that left over the mass fit's window: a record
    where grains of 2 g leave at 300 per s from 0.05 s gives 0.6 kg/s and 2 g a grain; grains
    carrying half that (a hybrid's light grains) show as 1 g each at the same grain rate."""
    from hgtools.discharge import measure
    t = np.arange(0.0, 0.5001, 0.01)
    for each in (0.002, 0.001):
        n_out = np.floor(300 * np.maximum(t - 0.05, 0))
        m_out = each * n_out
        mass0 = 10.0
        rows = np.column_stack([t, mass0 - m_out, 0.25 * m_out, 0.75 * m_out, 5000 - n_out, np.floor(0.25 * n_out),
                                n_out - np.floor(0.25 * n_out), 5000 - (n_out - np.floor(0.25 * n_out))])
        path = tmp_path / "discharge.dat"
        np.savetxt(path, rows, header="t M_in M_fall M_del N_in N_fall N_del N_all")
        figures, _ = measure(path, mass0)
        assert figures["grain_rate"] == pytest.approx(300, rel=0.01)
        assert figures["rate"] / figures["grain_rate"] == pytest.approx(each, rel=0.01)


def test_rate_standard_error_is_the_spread_of_rates_over_realizations():
    """hgtools.discharge.rate_standard_error against synthetic discharges whose spread is known:
    grains leaving as a Poisson process (rate 2,400 per s, records every 0.01 s, the 0.3 s window
    of the 2D silo's runs) have a fitted rate uncertain by 1/sqrt(720) = 3.7 %; over 400
    realizations the mean estimate must match both that and the spread of the fitted rates
    themselves (batch means are unbiased when the blocks are uncorrelated). Grains leaving one by
    one at a steady pace (no bursts) give an error far below Poisson's."""
    from hgtools.discharge import fit_rate
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 0.4001, 0.01)
    each, per_s = 0.008, 2400.0
    fits = [fit_rate(t, each * np.concatenate([[0], np.cumsum(rng.poisson(per_s * 0.01, len(t) - 1))]), 1e3)
            for _ in range(400)]
    rates = np.array([f["rate"] for f in fits])
    se = np.array([f["rate_se"] for f in fits])
    poisson = each * per_s / np.sqrt(per_s * 0.3)
    assert np.mean(se) == pytest.approx(poisson, rel=0.1)
    assert np.std(rates, ddof=1) == pytest.approx(poisson, rel=0.15)
    steady = fit_rate(t, each * np.floor(per_s * t), 1e3)
    assert steady["rate"] == pytest.approx(each * per_s, rel=1e-3)
    assert steady["rate_se"] < 0.1 * poisson


TIMED_LOG = """fix hybrid/mpm timing breakdown (8 exchanges, 4 rezones):
Section |  min time  |  avg time  |  max time  |%varavg| %total
---------------------------------------------------------------
MPM wait| 0.0019185  | 0.0019484  | 0.0019782  |   0.1 |  2.96
Coupling| 0.0049024  | 0.0049367  | 0.0049709  |   0.0 |  7.51
DEM side (LAMMPS timer, avg): Pair 7.6331e-05 Neigh 6.4094e-05 Comm 0.0016406 Modify 0.0051922 s
MPI task timing breakdown:
Section |  min time  |  avg time  |  max time  |%varavg| %total
---------------------------------------------------------------
Pair    | 3.8088     | 4.3008     | 4.7928     |  23.7 | 15.16
Other   |            | 0.8905     |            |       |  3.14

fix hybrid/mpm timing breakdown (2 exchanges, 0 rezones):
Section |  min time  |  avg time  |  max time  |%varavg| %total
---------------------------------------------------------------
MPM wait| 1.0        | 2.0        | 3.0        |   0.1 |  2.96
"""


def test_timing_sections_sum_each_tables_mean_over_the_runs():
    fix = logs.timing_sections(TIMED_LOG, "fix hybrid/mpm timing breakdown")
    assert fix == pytest.approx({"MPM wait": 2.0019484, "Coupling": 0.0049367})
    assert logs.timing_sections(TIMED_LOG, "MPI task timing breakdown") == pytest.approx({"Pair": 4.3008, "Other": 0.8905})


def test_mpm_ledger_reads_the_last_wall_time_line():
    text = ("mpm_solver: wall time 9 s: waiting for the DEM host 9, G2P 0\n"
            "mpm_solver: wall time 155 s: waiting for the DEM host 131, agreement 2.09, G2P 5.91, other 0.0148\n")
    assert logs.mpm_ledger(text) == {"wall": 155.0, "waiting for the DEM host": 131.0, "agreement": 2.09,
                                     "G2P": 5.91, "other": 0.0148}
    with pytest.raises(RuntimeError, match="no 'mpm_solver: wall time' line"):
        logs.mpm_ledger("mpm_solver: coupled run finished at LAMMPS step 10\n")


def test_a_hybrids_deposit_runs_through_its_continuum_to_the_grains_at_its_front():
    """A deposit of grains at the back wall, continuum (points on a grid of 6 d cells, two per cell
    and axis) from 10 d to 40 d, grains again to 50 d: the grains alone end the deposit at 10 d
    and count the front's grains detached; with the points its front is the far grains'."""
    from hgtools.collapse import measure
    d, cell = 0.002, 0.012

    def row(x0, x1):    # a floor row of touching grains of diameter d
        return np.arange(x0 + d / 2, x1, d)

    gx = np.concatenate([row(0, 10 * d), row(40 * d, 50 * d)])
    grains = dict(type=np.ones(len(gx), dtype=int), x=gx, y=np.full(len(gx), d / 2), radius=np.full(len(gx), d / 2),
                  vx=np.zeros(len(gx)), vy=np.zeros(len(gx)))
    px = np.arange(10 * d + cell / 4, 40 * d, cell / 2)
    points = dict(position=np.column_stack([px, np.full(len(px), cell / 4)]), volume=np.full(len(px), (cell / 2) ** 2))
    alone = measure(grains, grains, 5 * d, d)
    assert alone["front"] == pytest.approx(10 * d)
    assert alone["detached"] == 10
    hybrid = measure(grains, grains, 5 * d, d, points=points, cell=cell)
    assert hybrid["front"] == pytest.approx(50 * d)
    assert hybrid["runout"] == pytest.approx(9.0)
    assert hybrid["detached"] == 0
    # points that the continuum left behind, farther than half a cell from the rest, stay out of it
    stray = dict(position=np.vstack([points["position"], [[80 * d, cell / 4]]]),
                 volume=np.append(points["volume"], (cell / 2) ** 2))
    assert measure(grains, grains, 5 * d, d, points=stray, cell=cell)["front"] == pytest.approx(50 * d)
    with pytest.raises(ValueError, match="needs the grid's cell"):    # a point's reach is half a cell
        measure(grains, grains, 5 * d, d, points=points)
