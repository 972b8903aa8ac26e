"""High-speed impact of a large sphere into a settled 3D granular bed (issue 5), in three forms
sharing one parameter set: stock LAMMPS (input_decks/impact/dem_3d.lmp), LIGGGHTS (liggghts_3d.in,
the twin deck) and the hybrid twin (dem_3d.lmp + hybrid_3d.lmp, fix hybrid/mpm with adaptive
zones, through tools/hybrid_launch.py); driven by tools/dem_impact.py.

Reduced scene: a box of 12 floor rows (28.8 mm = 14.4 d) square, walls on all sides and a
lid, a bed of ~2500 spheres of d = 2 mm (diameters in [0.9, 1.1] d, rho = 2500 kg/m^3) settled
and trimmed to 24 mm = 12 d on a floor of frozen spheres; a glass projectile of dp = 12 mm =
6 d (rho_p = 2500 kg/m^3, 2.26 g) shot down at v0 = 4 m/s on the box axis (Froude number
v0^2/(g dp) = 136). Contacts: linear spring-dashpot with tangential history, e = 0.5, mu = 0.5,
kt = 2/7 kn; the impact stiffness is scaled with v0, kn = 2500 mref (v0/d)^2 = 1.05e5 N/m
(a grain hit at v0 overlaps 2 % of d), dt = tc/20 = 9.6e-7 s; the bed is settled with the soft
kns = 2000 rho g H d = 2354 N/m and stiffened before the launch (see the deck's header).
The bed is settled once by LAMMPS (prep stage) and all three forms shoot into that same bed
(write_data file): the comparisons are between the codes, not between packings.

Measured (this machine, one rank, heavily shared; LIGGGHTS on LAMMPS's bed of the same seed;
seeds 2024 / 1 / 7):
    penetration depth, mm        LAMMPS 11.19 / 12.03 / 11.49   LIGGGHTS 10.98 / 11.43 / 11.68
    |LAMMPS - LIGGGHTS| / mean   1.9 % / 5.1 % / 1.6 %
    stopping time, ms            LAMMPS 24.5 / 31.8 / 28.5      LIGGGHTS 25.6 / 32.1 / 30.1
    depth / Uehara et al.        LAMMPS 0.62 / 0.67 / 0.64      LIGGGHTS 0.61 / 0.63 / 0.65
    Katsuragi-Durian d1, mm      LAMMPS 3.2 / 2.1 / 2.3         LIGGGHTS 3.0 / 2.1 / 2.3
      (R^2 of the binned fit 0.73 / 0.95 / 0.91 in both codes; peak deceleration 670-1040 g)
    wall time, s                 LAMMPS settling 52-136, impact 24-104; LIGGGHTS impact 51-85
                                 (load average 6-10 on 2 cores; unloaded about a third)
This module (2 ranks, seed 2024, same load): LAMMPS 11.64 mm, LIGGGHTS 11.28 mm (3.1 %),
hybrid 9.79 mm (-15.9 %), 16 passed; 825 s wall under a load average of 8-10 (settling 308 s,
impacts 177 / 251 / 84 s: two MPI ranks suffer most from a shared machine). At a load
average of ~3 the one-rank times were: settling 28 s, impacts 26 / 52 / 54 s (2.7 min in all).
Different packings (seeds) of one code spread the depth over 7 % of its mean (LAMMPS,
11.19-12.03 mm) and the stopping time over 26 %; the two codes on one packing differ by at
most 5 % (depth) and 5 % (stopping time). The tolerance LAMMPS vs LIGGGHTS is TOLERANCE = 12 %
of the mean depth, 2.4x the largest same-bed difference and above the seed spread; the
stopping times (defined by a speed threshold on a slow creep, so noisier) within 24 %.

Published law (Uehara et al., PRL 90, 194301, 2003): d = (0.14/mu) (rho_p/rho_b)^(1/2)
dp^(2/3) H^(1/3), H = v0^2/(2 g) + d (+ the launch gap), with mu = 0.5 (the contact friction
standing for the tangent of the angle of repose) and rho_b = phi rho measured. The law was
fitted to low-speed drops of balls into deep, wide, loose beds of beads (the paper's title:
"Low-speed impact craters in loose granular media"); here v0 = 4 m/s (h = 0.82 m), the
bed is settled (phi = 0.59) and only 12 d deep (the projectile stops ~6 d above the frozen
floor, which stiffens the response), the walls are 4 d from the projectile, and the grains
have no rolling resistance: the depth
is asserted within a factor UEHARA_FACTOR = 2 of the law (measured 0.61-0.67x). The
deceleration history must follow the Katsuragi-Durian form F = m g + k z + m v^2/d1 on
depth bins (R^2 >= 0.5, 0 < d1 < dp): the peak deceleration at the contact, 670-1040 g, is of
the order of the inertial drag v0^2/d1 = 540-780 g (k, the depth term, is small and of either
sign in this shallow bed, so it is reported, not asserted).

Hybrid twin: in the reduced box there is no room for continuum cells with the silo's zone
settings (cells 2.5 d, depth 2 cells, band 1 cell: the discrete cylinder of radius dp around
the axis plus the oracle's margins fill the box; the coupled run is then pure DEM, 11.25 mm
against LAMMPS's 11.19 mm on seed 2024's bed). The test uses hybrid_3d.lmp's defaults, cells
of 2 d, depth 2.2 d, band 1.8 d: the bed's corners beyond the cylinder (r > dp + 0.4 d) become
hybrid (grains at half weight plus material points; no
continuum cell fits), 116-155 cells and ~1000 points. Measured on LAMMPS's beds (seeds 2024 /
1 / 7): 9.75 / 10.18 / 10.57 mm, i.e. -12.9 / -15.4 / -8.0 % against LAMMPS on the same bed
(mean -12 %: the coupled corners make the bed around the crater stiffer; a systematic bias of
the coupling, reported, not hidden by the tolerance), the fix's total mass constant to
round-off (0.0 relative change), grains made from points 8-9 (before hybrid cells needed a
continuum near: now the bed has no coupled cell at this size, and the hybrid is the DEM run). Asserted: the hybrid depth
within HYBRID_TOLERANCE = 25 % of LAMMPS's on the same bed (1.6x the largest measured
deviation, -15.9 % in this module's 2-rank run), the total mass constant to 1e-12, and no coupled cells (none lies deep enough). With the
coupling cells pushed closer to the crater (discrete cylinder of 8 mm = 1.33 projectile radii)
the depth fell 37 % short (6.92 mm): the crater must stay in grains.

If LIGGGHTS or the hybrid programs are missing, the test fails (never skips) with the reason.
"""
from __future__ import annotations

import math

import pytest

from conftest import assert_twin_params_agree
from dem_impact import run

WIDTH_ROWS, DEPTH, D, DP, SPEED, RHOP = 12, 0.024, 0.002, 0.012, 4.0, 2500.0
SEED = 2024
NP = 2                    # LAMMPS and LIGGGHTS ranks
HYBRID_NP = 1             # the hybrid: one LAMMPS rank plus the MPM process (2 cores)
TOLERANCE = 0.12          # |depth_lammps - depth_liggghts| / mean below this
UEHARA_FACTOR = 2.0       # depth within [1/2, 2] x Uehara et al.'s law
HYBRID_TOLERANCE = 0.25   # |depth_hybrid - depth_lammps| / depth_lammps below this
HYBRID_VARS = dict(hcell=0.004, hdepth=0.0044, hband=0.0036, hradius=DP)   # hybrid_3d.lmp's defaults
OVERLAP_MAX = 0.03        # the largest sampled overlap and the deck's estimate at v0, in d


@pytest.fixture(scope="module")
def results(tmp_path_factory, lmp, liggghts, hybrid_programs):
    out = {}
    common = dict(width_rows=WIDTH_ROWS, depth=DEPTH, d=D, dp=DP, speed=SPEED, rhop=RHOP, np_=NP, seed=SEED,
                  timeout=900)
    out["lammps"] = run("lammps", out=tmp_path_factory.mktemp("impact_lammps"), **common)
    bed = out["lammps"].bed
    try:
        out["liggghts"] = run("liggghts", out=tmp_path_factory.mktemp("impact_liggghts"), bed=bed, **common)
    except RuntimeError as exc:
        pytest.fail(f"LIGGGHTS could not run input_decks/impact/liggghts_3d.in:\n{exc}")
    out["hybrid"] = run("hybrid", out=tmp_path_factory.mktemp("impact_hybrid"), bed=bed,
                        hybrid_vars=HYBRID_VARS, **dict(common, np_=HYBRID_NP))
    for res in out.values():
        print(res.log)
        print(res.summary())
    return out


def test_same_parameters(results):
    """The twin decks printed the same contact parameters and time step; kn is scaled with v0."""
    assert_twin_params_agree(results)
    a = results["lammps"].params
    mref = 2500.0 * math.pi / 6 * D ** 3
    assert a["kn"] == pytest.approx(2500 * mref * (SPEED / D) ** 2, rel=1e-9)
    assert a["kt"] == pytest.approx(2.0 / 7.0 * a["kn"], rel=1e-9)


@pytest.mark.parametrize("code", ["lammps", "liggghts", "hybrid"])
def test_high_speed_and_small_overlaps(results, code):
    res = results[code]
    assert res.froude > 50, res.summary()
    assert 2000 <= res.grains <= 3200, res.summary()
    assert res.overlap_expected <= OVERLAP_MAX, res.summary()
    # sampled overlaps (settled bed, final state) stay far below the impact estimate
    assert res.max_overlap_initial < OVERLAP_MAX and res.max_overlap_final < OVERLAP_MAX, res.summary()


@pytest.mark.parametrize("code", ["lammps", "liggghts", "hybrid"])
def test_projectile_stops_in_the_bed(results, code):
    res = results[code]
    assert res.at_rest, res.summary()
    # it went in, by more than a grain and less than the bed depth minus its own size
    assert 2 * D < res.penetration < DEPTH - 0.5 * DP, res.summary()
    assert 0 < res.stop_time <= res.end_time, res.summary()
    # the bed decelerates it hard at the contact (inertial drag, hundreds of g)
    assert res.peak_decel > 100 * 9.81, res.summary()


def test_lammps_and_liggghts_agree(results):
    a, b = results["lammps"].penetration, results["liggghts"].penetration
    assert abs(a - b) / (0.5 * (a + b)) < TOLERANCE, (results["lammps"].summary(), results["liggghts"].summary())
    sa, sb = results["lammps"].stop_time, results["liggghts"].stop_time
    assert abs(sa - sb) / (0.5 * (sa + sb)) < 2 * TOLERANCE, (sa, sb)


@pytest.mark.parametrize("code", ["lammps", "liggghts"])
def test_uehara_law(results, code):
    res = results[code]
    assert 1.0 / UEHARA_FACTOR < res.ratio < UEHARA_FACTOR, res.summary()


@pytest.mark.parametrize("code", ["lammps", "liggghts"])
def test_katsuragi_durian_form(results, code):
    res = results[code]
    assert res.drag_r2 >= 0.5, res.summary()
    assert 0 < res.drag_d1 < DP, res.summary()


@pytest.mark.parametrize("code", ["lammps", "liggghts", "hybrid"])
def test_energy_bounded_no_lost_atoms(results, code):
    res = results[code]
    # the projectile's energy (kinetic + rotational + m g z) never exceeds its launch value
    assert res.proj_energy_gain <= 1e-9 * res.ke0, res.summary()
    if code != "hybrid":
        # nor does that of everything that moves (the bed's stored elastic energy is ~1e-6 KE0)
        assert res.mobile_energy_gain <= 1e-3 * res.ke0, res.summary()
        assert res.atoms_end == res.atoms_launch, res.summary()


def test_hybrid_matches_lammps_and_conserves_mass(results):
    hyb, lmp = results["hybrid"], results["lammps"]
    # No cell of this bed lies deeper than depth + band from its walls, floor, surface and the
    # discrete cylinder, so there is no continuum, and hybrid cells need one near (the oracle's
    # rule since 2026-11-24; before it, hybrid corners stiffened the bed: depth -8 to -16 %).
    # The coupled run is then the DEM run, exactly.
    assert hyb.hybrid_cells == 0 and hyb.hybrid_points == 0, hyb.summary()
    assert hyb.mass_balance < 1e-12, hyb.summary()
    assert abs(hyb.penetration - lmp.penetration) / lmp.penetration < HYBRID_TOLERANCE, \
        (hyb.summary(), lmp.summary())
