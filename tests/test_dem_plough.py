"""The quasi-3D plough in three forms (tools/dem_plough.py; input_decks/plough/): a rigid
vertical blade (a sheet of spheres moved by fix move) inserted to depth h into a settled bed
and dragged in x at V = 0.1 m/s; the measure is the mean horizontal drag over the second half
of a drag of 3 h (blade displacement 1.5 h to 3 h).

Reduced scenes (d = 2 mm, diameters uniform in [0.9, 1.1] d, rho = 2500 kg/m^3, e = 0.5,
mu = 0.5, kn = 200 rho g H d, kt = 2/7 kn, dt = tc/20, blade top edge h/4 above the bed):
  * LAMMPS vs LIGGGHTS: h = 4 d, H = 8 d, slab W = 4.8 d periodic in z, ~1400 grains;
  * hybrid vs LAMMPS: h = 4 d, H = 12 d, slab W = 10.8 d between frictionless side walls
    (zwall 1: fix hybrid/mpm needs fixed boundaries, and its continuum needs cells
    depth + band away from every wall, which a ~5 d slab does not have), ~4700 grains; the
    hybrid twin (hybrid_3d.lmp) turns the deep bed ahead of and below the blade into
    continuum, with a discrete region that moves with the blade. lmp_hybrid is the same
    LAMMPS as lmp: both runs reach the coupling (after the insertion) in the bit-identical
    state, so they differ only by the coupling.

Measured (2 MPI ranks, this machine; data-file seeds 2024 / 1 / 7; drag in N):
    LAMMPS 29Sep2021     0.0392 / 0.0386 / 0.0401     F/F_R 3.56 / 3.49 / 3.65
    LIGGGHTS 3.8.0       0.0362 / 0.0372 / (not run)  F/F_R 3.28 / 3.39
    |LAMMPS - LIGGGHTS| / mean: 7.9 % (seed 2024), 3.8 % (seed 1)
    thick slab, seeds 2024 / 1: LAMMPS 0.0835 / 0.0822, hybrid 0.0826 / 0.0861 (-1.1 % / +4.7 %;
    F/F_R 3.25-3.41; 9-10 continuum and ~130 hybrid cells of 1500, ~1100 material points;
    total mass, f_couple[8], unchanged to the 12 digits printed)
    (LIGGGHTS with zwall 1 on the thin slab, seed 2024: 0.0362, F/F_R 3.45.)
Wall times (the thick runs: 4709 grains): on a quieter machine a thin run took 4-10 s and the
hybrid one 31 s; with the two cores shared with three other jobs (load
average ~8) the whole module took 9.9 minutes (thin LAMMPS ~1 min, LIGGGHTS ~2.5 min, thick
LAMMPS 4.6 min, hybrid 1.9 min), with 5.8 minutes of CPU time in all, i.e. ~3 minutes of the
two cores alone (Open MPI's busy polling of oversubscribed ranks makes up the rest).
In the hybrid run 178 grains became points and 49 grains were made from points as the blade's
discrete region advanced.
The mean over the window of one code moves by ~2-4 % between packings (the drag itself
fluctuates by 15-30 % of its mean from one 5 ms record to the next: force chains build and
fail; the means of the window's four quarters spread by ~10 %), and LIGGGHTS is lower by ~6 %
on average (one known difference of the contact law: while sliding, LIGGGHTS drops the
tangential damping that LAMMPS caps with the spring, see the column deck's header):
TOLERANCE = 15 % of the mean, about twice the largest difference measured.

Published law: Rankine's passive earth pressure, F_R = 1/2 K_p rho_b g h^2 W with
K_p = (1 + sin phi)/(1 - sin phi), phi = 27 deg (K_p = 2.66), rho_b measured in the settled bed,
h the measured depth of the lower edge below the settled surface. Measured F/F_R = 3.3-3.6
(both codes). Rankine's wall is smooth and the surface behind it flat: it is the smallest
passive resistance. Our blade is rough (mu = 0.5, wall friction angle up to 26.6 deg: Coulomb's
passive wedge with a wall friction angle of phi gives 2.3 times Rankine's horizontal force), and
in a slab the material it pushes heaps up in front of it to about h above the surface before
spilling over its top (a surcharge). The test asserts RANKINE_BAND = 1 <= F/F_R <= 6: at least
Rankine's, at most Coulomb's rough-wall factor times a surcharge factor of ~2.5.

Hybrid: the coupled run (lmp_hybrid + mpm_solver) of the thick slab must drag within
HYBRID_TOLERANCE = 15 % of the pure LAMMPS run of the same data file (measured -1.1 % and
+4.7 %; the tolerance is the code-to-code one, 3x the largest difference measured: the window
mean of one packing is known to ~4 % (the two thick LAMMPS packings differ by 1.6 %), the hybrid
adds half-mass grains in its hybrid cells, and the adaptive runs of the silo and the column
were off by a few to tens of per cent, docs/fix_hybrid_mpm.md), and keep the total mass (grains'
carried mass plus points, fix hybrid/mpm's f_couple[8]) to round-off. The continuum of this
reduced slab is small (see above): the test checks that the coupling runs around a moving
intruder and leaves the drag alone, not that a large continuum reproduces it.
"""
from __future__ import annotations


import pytest

from conftest import assert_twin_params_agree
from dem_plough import run

DEPTH, D = 0.008, 0.002
SEED = 2024
NP = 2
TOLERANCE = 0.15                # |F_lammps - F_liggghts| / mean(F)
RANKINE_BAND = (1.0, 6.0)       # F / F_Rankine
HYBRID_TOLERANCE = 0.15         # |F_hybrid - F_lammps| / F_lammps (same slab, walls, data file)
THICK = dict(bedh=0.024, thickness_d=9)


@pytest.fixture(scope="module")
def results(tmp_path_factory, lmp, liggghts):
    out = {}
    out["lammps"] = run("lammps", DEPTH, d=D, np_=NP, seed=SEED, out=tmp_path_factory.mktemp("plough_lammps"),
                        exe=lmp)
    try:
        out["liggghts"] = run("liggghts", DEPTH, d=D, np_=NP, seed=SEED,
                              out=tmp_path_factory.mktemp("plough_liggghts"), exe=liggghts)
    except RuntimeError as exc:
        pytest.fail(f"LIGGGHTS could not run the plough deck (input_decks/plough/liggghts_3d.in):\n{exc}")
    out["walls_dir"] = tmp_path_factory.mktemp("plough_lammps_walls")
    out["lammps_walls"] = run("lammps", DEPTH, d=D, np_=NP, seed=SEED, extra_vars={"zwall": 1},
                              out=out["walls_dir"], exe=lmp, **THICK)
    for key in ("lammps", "liggghts", "lammps_walls"):
        print(out[key].log)
        print(out[key].summary())
    return out


@pytest.fixture(scope="module")
def hybrid(results, hybrid_programs, tmp_path_factory):
    path = tmp_path_factory.mktemp("plough_hybrid")
    res = run("hybrid", DEPTH, d=D, np_=NP, seed=SEED, out=path, **THICK)
    print(res.log)
    print(res.summary())
    res.out_dir = path
    return res


def test_same_parameters(results):
    """The twin decks printed the same contact parameters and timestep."""
    assert_twin_params_agree(results)


@pytest.mark.parametrize("code", ["lammps", "liggghts", "lammps_walls"])
def test_settled_bed_and_insertion(results, code):
    res = results[code]
    assert res.grains > 1000, res.summary()
    assert 0.55 < res.packing < 0.65, res.summary()              # random packing of spheres
    assert abs(res.surface - res.bedh) < res.d, res.summary()    # trimmed to H
    assert abs(res.depth_actual - res.depth) < 0.5 * res.d, res.summary()
    assert res.blade_top > 0.5 * res.d, res.summary()            # the blade sticks out of the bed
    assert res.max_overlap < 0.03, res.summary()                 # stiff enough (overlaps ~1 % d)
    assert res.mass_end == pytest.approx(res.mass, rel=1e-12)    # no grain lost
    assert res.drag > 0, res.summary()


def test_lammps_liggghts_drag_agree(results):
    a, b = results["lammps"].drag, results["liggghts"].drag
    diff = abs(a - b) / (0.5 * (a + b))
    print(f"drag LAMMPS {a:.4g} N, LIGGGHTS {b:.4g} N: difference {diff:.1%} (tolerance {TOLERANCE:.0%})")
    assert diff < TOLERANCE


@pytest.mark.parametrize("code", ["lammps", "liggghts", "lammps_walls"])
def test_drag_of_the_order_of_rankine(results, code):
    res = results[code]
    lo, hi = RANKINE_BAND
    assert lo <= res.ratio <= hi, res.summary()


def test_hybrid_drag_close_to_dem_and_mass_conserved(results, hybrid):
    dem = results["lammps_walls"]
    h = hybrid.hybrid
    assert h, "no thermo lines of fix hybrid/mpm in the hybrid run's log"
    # the continuum exists (points, continuum cells)
    assert h["points_max"] > 100 and h["continuum_cells_max"] > 0, hybrid.summary()
    assert h["mass_drift"] < 1e-10, hybrid.summary()
    # same program version and ranks: the coupling starts from the DEM run's state exactly
    assert (hybrid.out_dir / "inserted.dump").read_bytes() == (results["walls_dir"] / "inserted.dump").read_bytes()
    diff = abs(hybrid.drag - dem.drag) / dem.drag
    print(f"drag LAMMPS (walls) {dem.drag:.4g} N, hybrid {hybrid.drag:.4g} N: difference {diff:.1%} "
          f"(tolerance {HYBRID_TOLERANCE:.0%})")
    assert diff < HYBRID_TOLERANCE
