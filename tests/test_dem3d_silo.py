"""3D flat-bottomed silo discharge in three forms sharing one parameter set (tools/dem3d_silo.py):
stock LAMMPS (input_decks/silo/dem_3d.lmp), LIGGGHTS (liggghts_3d.in) and the hybrid twin
(dem_3d.lmp + hybrid_3d.lmp, fix hybrid/mpm with adaptive zones, through tools/hybrid_launch.py).

Scene (reduced): a silo of square cross-section W = 0.03 m = 15 d (side walls at x = 0, W and
z = 0, W), filled to H = 0.04 m = 20 d with ~4700 spheres of d = 2 mm (diameters uniform in
[0.9, 1.1] d, rho = 2500 kg/m^3), on a floor of frozen spheres (square lattice, 13 x 13 rows)
with a circular orifice of nominal D = 0.012 m = 6 d left out (inscribed diameter of the
lattice hole D_eff = 6.30 d). Linear spring-dashpot with tangential history, e = 0.5, mu = 0.5
(grains, floor, walls), kt = 2/7 kn, kn = 200 rho g H d, dt = tc/20. LAMMPS prepares the settled
silo on 2 ranks (pour, settle, trim, settle with the orifice closed by a plane just below the
floor) and writes it as a data file; each form discharges that same packing (no contact
histories in data files: all three start from the same state) until half of the mass has left.

Measured (this machine; discharge rate W = slope of the discharged mass from 0.1 s after the
opening until half of the mass has left, tools/hgtools/discharge.fit_rate):
  test scene (H = 20 d, seed 2024, 2 ranks): 4740 grains, 0.0501 kg, packing fraction 0.591;
    LAMMPS 0.03346 kg/s, LIGGGHTS 0.03348 kg/s (+0.0 %), halves within 4 %, 1.38 x Beverloo;
    largest overlap 2.0 % of d; mass balance ~1e-14 in both codes.
  codes from one packing (LIGGGHTS / LAMMPS - 1):
    H = 20 d, 2 ranks, seeds 2024 / 1 / 2:        +0.0 / -2.5 / +1.5 %
    H = 15 d, 1 rank, seeds 2024 / 1 / 2 / 3:     -3.8 / -0.6 / +2.7 / -2.1 %
  LAMMPS alone spreads 0.0326-0.0335 kg/s over the three packings at H = 20 d (1.5 % rms) and
  0.0326-0.0343 over the four at H = 15 d (2.4 % rms; LIGGGHTS 3.4 %); all fourteen rates are
  1.32-1.42 x Beverloo.
So LAMMPS and LIGGGHTS must agree within CODE_TOLERANCE = 10 %: 2.6 x the largest difference
measured (3.8 %), about 3 x the spread between packings of one code (the two codes' chaotic
trajectories diverge within the first collisions, so the difference is noise of the kind
that separates packings, not a bias: its mean over the seven pairs is -0.7 %).
Beverloo (docs/design.md sec. 6, C = 0.58, k = 1.5, rho_b = phi rho, D = the inscribed diameter of
the lattice hole, 6.3 d): the measured rate is ~1.4 x higher. Expected direction: the opening
between the edge spheres is wider than its inscribed circle, the silo is narrow (W = 2.4 D,
walls closer than Nedderman's W > D + 30 d), the spheres have no rolling resistance, and
at D/d = 6.3 the law hangs on k ((D - k d)^2.5 changes 5 % per 0.1 of k; k = 2 instead of
1.5 would lower it by 24 %). The test asks for a factor BEVERLOO_FACTOR = 1.6.
Hybrid twin (hybrid_3d.lmp's defaults: cell 2 d, depth 2 cells, band 1 cell, a discrete
cylinder over the orifice up to D, exchange every 20 steps; from the same packing): 0.03124
kg/s on 2 ranks, -6.6 % against LAMMPS (-3.5 % on one rank over 0.1-0.6 s); 259 rezones, 1712
points made, 3 grains made from points, at most 1 continuum and 130 hybrid cells (this silo is
too narrow for more continuum: it keeps depth + band from both pairs of walls). Two runs of
the module gave the same rates and rezone counts to the last digit. Exchanging every 10 steps
(hybrid_2d.lmp's default) the hybrid was 18 % slow, with 3 mm cells about 50 % slow (see
hybrid_3d.lmp's header). HYBRID_TOLERANCE = 15 %: ~2 x the measured error; the 2D silo's
test allows 20 % per packing.
Wall time (2 ranks each, on the shared machine): 88 s for the module at load ~3 (preparation,
LAMMPS and LIGGGHTS discharges 62 s together, hybrid 26 s; 2 min 25 s in an earlier run);
at load ~8 the same module took 18.5 min.

If LAMMPS, LIGGGHTS or the coupled programs are missing or fail, the test fails (never skips).
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import assert_twin_params_agree
from dem3d_silo import run
from hgtools.discharge import rate_ratio_se

WIDTH, HEIGHT, ORIFICE, D = 0.03, 0.04, 0.012, 0.002
SEED, NP = 2024, 2
FSTOP, TDIS = 0.5, 1.0
CODE_TOLERANCE = 0.10    # |W_liggghts / W_lammps - 1| from the same packing
BEVERLOO_FACTOR = 1.6    # the rate within a factor 1.6 of the 3D Beverloo law (C = 0.58, k = 1.5)
HALVES_SPREAD = 0.15     # the two halves of the steady window agree within 15 %
FIT_RESIDUAL = 0.02      # rms residual of the linear fit below 2 % of the window's discharged mass
HYBRID_TOLERANCE = 0.15  # |W_hybrid / W_lammps - 1| from the same packing
# hybrid_3d.lmp's defaults (cell 2 d, depth 2 cells, band 1, outlet region up to D, every 20), with every
# rezone's line in the log (the test below reads them)
HYBRID_VARS: dict = {"hlog": "full"}


@pytest.fixture(scope="module")
def silo_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("dem3d_silo")


def _common(silo_dir):
    return dict(width=WIDTH, height=HEIGHT, orifice=ORIFICE, d=D, np_=NP, seed=SEED, prep_code="lammps",
                cache_dir=silo_dir / "cache", tdis=TDIS, fstop=FSTOP, timeout=900)


@pytest.fixture(scope="module")
def results(silo_dir, lmp, liggghts):
    """LAMMPS prepares the settled silo (in the test's own cache, so that the closed-orifice
    checks see a preparation of this run); LAMMPS and LIGGGHTS discharge it."""
    out = {}
    out["lammps"] = run("lammps", out=silo_dir / "lammps", exe=lmp, **_common(silo_dir))
    try:
        out["liggghts"] = run("liggghts", out=silo_dir / "liggghts", exe=liggghts, **_common(silo_dir))
    except RuntimeError as exc:
        pytest.fail(f"LIGGGHTS could not run the 3D silo deck (input_decks/silo/liggghts_3d.in):\n{exc}")
    for res in out.values():
        print(res.log)
        print(res.summary())
    return out


def test_closed_orifice_holds_the_settled_grains(results):
    res = results["lammps"]
    assert res.prepared and not results["liggghts"].prepared
    assert 3500 <= res.grains <= 6000, res.summary()
    # filled as asked: the free surface at H within two grain diameters
    assert abs(res.fill_height - HEIGHT) < 2 * D, res.summary()
    # nothing went through the closed orifice, and the mass after trimming is all there at the
    # opening (in both codes: they read the same data file)
    assert res.settled_below == 0, res.summary()
    assert res.settled_mass == pytest.approx(res.trimmed_mass, rel=1e-12)
    for r in results.values():
        assert r.mass0 == pytest.approx(res.settled_mass, rel=1e-12)
        assert r.grains == res.grains
    # a random loose-to-dense packing of spheres in a narrow silo (walls loosen it)
    assert 0.55 < res.packing < 0.64, res.summary()
    # contacts stiff enough: kn = 200 rho g H d gives a mean overlap ~0.2 % of d; the largest,
    # in force chains near the floor, measured 1.7-2.3 % over seven packings
    assert res.max_overlap_initial < 0.03, res.summary()
    # the orifice left out of the floor lattice is at least D wide
    assert ORIFICE <= res.orifice_eff < ORIFICE + D, res.summary()


def test_same_parameters(results):
    """The twin decks printed the same contact parameters and timestep."""
    assert_twin_params_agree(results, rel=1e-12)


@pytest.mark.parametrize("code", ["lammps", "liggghts"])
def test_mass_is_conserved(results, code):
    res = results[code]
    # every record: in the silo + falling below it + deleted = initial mass; no grain lost
    assert res.mass_balance < 1e-12, res.summary()
    assert res.lost == 0, res.summary()
    assert res.discharged_fraction >= FSTOP, res.summary()


@pytest.mark.parametrize("code", ["lammps", "liggghts"])
def test_discharge_is_steady(results, code):
    res = results[code]
    t_a, t_b = res.window
    assert t_b - t_a > 0.4, res.summary()
    assert res.halves_spread < HALVES_SPREAD, res.summary()
    assert res.fit_rel < FIT_RESIDUAL, res.summary()


def test_lammps_and_liggghts_rates_agree(results):
    a, b = results["lammps"], results["liggghts"]
    diff = b.rate / a.rate - 1
    print(f"rate: LAMMPS {a.rate:.5f} kg/s, LIGGGHTS {b.rate:.5f} kg/s: {diff:+.1%} ± {rate_ratio_se(b, a):.1%}")
    assert abs(diff) < CODE_TOLERANCE, (a.summary(), b.summary())


@pytest.mark.parametrize("code", ["lammps", "liggghts"])
def test_rate_matches_3d_beverloo(results, code):
    res = results[code]
    assert res.rate > 0
    assert 1 / BEVERLOO_FACTOR < res.ratio < BEVERLOO_FACTOR, res.summary()


# ---- the hybrid twin: adaptive zones (input_decks/silo/hybrid_3d.lmp) ----------------------

REZONE = re.compile(r"step \d+: (\d+) grains became (\d+) material points, \d+ grains are hybrid \(weight [\d.]+\), "
                    r"(\d+) grains made from points; \d+ cells moved; grid cells in the box: (\d+) continuum, "
                    r"(\d+) hybrid, (\d+) discrete; (\d+) cells gave their rest of material to nearby points, "
                    r"(\d+) kept it; carried mass / solid mass (\S+) to (\S+)")


def _coupled(code: str, silo_dir):
    """A hybrid discharge (code hybrid or hybrid_liggghts) from the same packing: result and log."""
    import os
    from conftest import BUILD
    os.environ.setdefault("HYBRID_BUILD_DIR", str(BUILD))
    os.environ["OMP_NUM_THREADS"] = "1"
    res = run(code, out=silo_dir / code, hybrid_vars=HYBRID_VARS, **_common(silo_dir))
    print(res.summary())
    return res, (silo_dir / code / "log.txt").read_text()


@pytest.fixture(scope="module")
def hybrid(results, silo_dir, hybrid_programs):
    return _coupled("hybrid", silo_dir)


def test_hybrid_silo_discharges_only_grains_made_from_the_continuum(results, hybrid):
    """Grains become points where the silo is deep, points become grains where the flow brings
    them near the floor and the outlet region; only grains leave. Grains plus points (the fix's
    total) plus the grains that left stay the initial mass."""
    res, log = hybrid
    assert not res.prepared and res.grains == results["lammps"].grains
    assert "Lost atoms" not in log
    rezones = [m.groups() for m in REZONE.finditer(log)]
    made_points = sum(int(r[1]) for r in rezones)
    made_grains = sum(int(r[2]) for r in rezones[1:])
    print(f"{len(rezones)} rezones: {made_points} points made, {made_grains} grains made from points, "
          f"at most {max(int(r[3]) for r in rezones)} continuum and {max(int(r[4]) for r in rezones)} hybrid cells")
    assert int(rezones[0][4]) > 20 and int(rezones[0][1]) > 200, rezones[0]   # coupled from the opening
    assert made_points > 500, made_points                                      # points kept being made
    assert made_grains > 0, "no grain made from points"                        # and turned back into grains
    # every grain carries its weight times its solid mass, within a rezone's bounds (as in 2D)
    lightest, heaviest = float(rezones[-1][8]), float(rezones[-1][9])
    assert 0.5 < lightest <= 1.0 + 1e-9 and 1.0 <= heaviest <= 2.0 + 1e-9, rezones[-1]
    # the thermo row at the end of the last run comes before the last deletion of the grains that
    # fell out: grains + points then, plus what was deleted before it = initial mass. The fix's
    # total (f_couple[8]) counts its group only, not the frozen floor spheres (res.floor_mass).
    rows = [ln.split() for ln in log.splitlines() if re.match(r"^\s*\d+\s+[\d.e+-]+\s+\d+\s+\d+\s", ln)]
    assert float(rows[0][7]) == pytest.approx(res.mass0, rel=1e-9)
    total_end = float(rows[-1][7])
    assert total_end + res.m_del[-2] == pytest.approx(res.mass0, rel=1e-9)
    assert res.m_fall[-1] + res.m_del[-1] >= 0.5 * res.mass0


def test_hybrid_silo_discharge_rate_matches_pure_dem(results, hybrid):
    res, _ = hybrid
    dem = results["lammps"]
    diff = res.rate / dem.rate - 1
    print(f"rate: hybrid {res.rate:.5f} kg/s against LAMMPS {dem.rate:.5f}: {diff:+.1%} ± {rate_ratio_se(res, dem):.1%}")
    assert abs(diff) < HYBRID_TOLERANCE, (res.summary(), dem.summary())


# ---- the LIGGGHTS-hosted hybrid twin (liggghts_3d.in + hybrid_3d.liggghts, liggghts_hybrid) ------

@pytest.fixture(scope="module")
def hybrid_liggghts(results, silo_dir, hybrid_programs):
    return _coupled("hybrid_liggghts", silo_dir)


def test_liggghts_hybrid_silo_is_coupled_and_discharges_at_the_pure_liggghts_rate(results, hybrid_liggghts):
    """The same coupling with LIGGGHTS as the DEM host, from the same packing: coupled from the
    opening (points made, hybrid cells), every rezone keeps the totals of grains plus points, and
    the rate is pure LIGGGHTS's within the LAMMPS hybrid twin's tolerance (measured: 0.03352
    against 0.03348 kg/s, +0.1 %, on 2 ranks)."""
    res, log = hybrid_liggghts
    assert not res.prepared and res.grains == results["liggghts"].grains
    rezones = [m.groups() for m in REZONE.finditer(log)]
    assert int(rezones[0][4]) > 20 and int(rezones[0][1]) > 200, rezones[0]
    totals = [np.array(m.group(1).split(), dtype=float).reshape(7, 2)
              for m in re.finditer(r"totals before/after the rezone:((?: \S+){14})", log)]
    assert len(totals) == len(rezones) > 1
    for t in totals:
        assert t[0, 1] == pytest.approx(t[0, 0], rel=1e-12)    # mass of grains plus points
    dem = results["liggghts"]
    diff = res.rate / dem.rate - 1
    print(f"rate: LIGGGHTS-hosted hybrid {res.rate:.5f} kg/s against LIGGGHTS {dem.rate:.5f}: {diff:+.1%}")
    assert abs(diff) < HYBRID_TOLERANCE, (res.summary(), dem.summary())
