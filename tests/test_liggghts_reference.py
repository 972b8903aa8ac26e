"""Pure-DEM references in LAMMPS and LIGGGHTS: the same reduced quasi-3D column collapse
(input_decks/column_collapse/dem_3d.lmp and liggghts_3d.in, driven by tools/dem3d_collapse.py)
run in both codes must agree on the normalised runout (Lf - L0)/L0.

Scene (shared parameter block of the two decks): a = 2, L0 = 0.03 m = 15 d, H0 = 0.06 m,
spheres of d = 2 mm, diameters uniform in [0.9, 1.1] d, rho = 2500 kg/m^3, in a slab of
thickness W = 4.8 d periodic in z, on a floor of frozen spheres (square lattice, 1.2 d),
back wall and end wall frictional, ~2330 grains after trimming. Contact law: linear
spring-dashpot with tangential history, kn = 200 rho g H0 d = 588.6 N/m, kt = 2/7 kn,
gamma_n = 4569 1/s (e = 0.5 for a mean-size pair; per unit effective mass in both codes,
LAMMPS gran/hooke/history and LIGGGHTS hooke/stiffness: same numbers), gamma_t = gamma_n/2,
mu = 0.5; dt = tc/20 = 1.29e-5 s. Both decks read the same initial grains (a data file), pour
and settle them behind a frictionless gate, trim to H0, remove the gate and run until the mean
kinetic energy per grain is below 1e-5 m g d.

Measured (2 MPI ranks, this machine; data-file seeds 2024 / 1 / 7):
    LAMMPS 29Sep2021     2.983 / 2.907 / 2.824   wall time 25 / 25 / 28 s
    LIGGGHTS 3.8.0       2.826 / 3.062 / 2.997   wall time 32 / 34 / 36 s
    |difference| / mean  5.4 % / 5.2 % / 6.0 %
The runs of one code from different seeds spread by ~5 % (2.82-3.06 over all six runs, the
chaotic run-to-run variability of DEM: each code builds its own packing from the same start),
so the two codes must agree within TOLERANCE = 15 % of their mean, about 2.5x the measured
difference. Both lie near the lower bound of the published law (1.9-2.3 a^(2/3) = 3.02-3.65
for a = 2); the band asserted is that range widened by 35 % for a thin periodic slab of
spheres without rolling resistance at L0 = 15 d.

If LIGGGHTS is missing or cannot run the scene, the test fails (never skips) with the reason.
"""
from __future__ import annotations


import pytest

from conftest import assert_twin_params_agree
from dem3d_collapse import run

TOLERANCE = 0.15      # |R_lammps - R_liggghts| / mean(R) must stay below this
BAND = 0.35           # runouts within the published range widened by 35 %
SEED = 2024
NP = 2


@pytest.fixture(scope="module")
def results(tmp_path_factory, lmp, liggghts):
    out = {}
    out["lammps"] = run("lammps", np_=NP, seed=SEED, out=tmp_path_factory.mktemp("dem3d_lammps"), exe=lmp)
    try:
        out["liggghts"] = run("liggghts", np_=NP, seed=SEED, out=tmp_path_factory.mktemp("dem3d_liggghts"),
                              exe=liggghts)
    except RuntimeError as exc:
        pytest.fail("LIGGGHTS could not run the 3D column collapse deck "
                    f"(input_decks/column_collapse/liggghts_3d.in):\n{exc}")
    for res in out.values():
        print(res.log)
        print(res.summary())
    return out


def test_same_parameters(results):
    """The twin decks printed the same contact parameters and timestep."""
    assert_twin_params_agree(results)


@pytest.mark.parametrize("code", ["lammps", "liggghts"])
def test_each_code_column_and_rest(results, code):
    res = results[code]
    assert 1500 <= res.grains <= 3000, res.summary()
    assert abs(res.height - res.aspect * res.width) < res.d, res.summary()
    # at rest: mean KE per grain below 1e-5 m g d, the connected deposit nearly still
    assert res.at_rest, res.summary()
    assert res.max_speed_deposit < 0.05, res.summary()
    # the column spread and lowered, the front well before the end wall
    assert res.final_height < 0.8 * res.height, res.summary()
    assert len(res.profile) > 5
    assert res.front < res.width * (1 + 2 * 2.3 * res.aspect ** (2 / 3)) - 5 * res.d
    # overlaps stay small (kn = 200 rho g H0 d: mean ~0.3 % of d; measured max <= 1.7 %)
    assert res.max_overlap_final < 0.02, res.summary()


@pytest.mark.parametrize("code", ["lammps", "liggghts"])
def test_runout_in_published_band(results, code):
    res = results[code]
    lo, hi = res.published
    assert (1 - BAND) * lo <= res.runout <= (1 + BAND) * hi, res.summary()


def test_codes_agree_on_runout(results):
    a, b = results["lammps"].runout, results["liggghts"].runout
    rel = abs(a - b) / (0.5 * (a + b))
    assert rel < TOLERANCE, (f"LAMMPS (Lf-L0)/L0 = {a:.3f}, LIGGGHTS {b:.3f}: differ by {100 * rel:.1f} % "
                             f"> {100 * TOLERANCE:.0f} %")
