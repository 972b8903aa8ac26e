"""bench/adaptive_accuracy.py: how its runs from several packings and several invocations add up.

The bench itself is not a test (its runs take an hour); its results file is read as the hybrid's
accuracy, so a rerun must replace exactly what it measures again and the means must be the rows'.
"""
from __future__ import annotations

import sys
from types import SimpleNamespace
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import adaptive_accuracy as bench  # noqa: E402


def collapse(seed=None, every=10, oracle=100, runout=0.0, floor=0.005, aspect=2.0, date="old") -> dict:
    r = dict(scene="collapse_2d", aspect=aspect, exchange_every=every, oracle_every=oracle, runout_error=runout,
             surface_error=0.013, rate_error=None, steps_ratio=1.0, noise_floor_runout=floor, date=date)
    if seed is not None:
        r["seed"] = seed
    return r


def test_a_rerun_replaces_only_the_rows_it_measures_again():
    kept = [collapse(every=1), collapse(every=10), collapse(seed=2, every=10), collapse(every=10, aspect=0.5),
            dict(scene="silo_3d", exchange_every=10, oracle_every=100, rate_error=0.01, date="old"),
            dict(scene="silo_2d", failed="timed out", date="old"),
            dict(scene="collapse_3d", failed="timed out", date="old")]
    new = [collapse(seed=bench.REFERENCE_SEED, every=10, date="new"), collapse(seed=3, every=10, date="new"),
           dict(scene="silo_2d", aspect=None, seed=bench.REFERENCE_SEED, exchange_every=10, oracle_every=100,
                rate_error=0.0, date="new")]
    merged = bench.merge(kept, new)
    # a row written before rows had a packing is the reference packing's: the new one replaces it
    assert [r for r in merged if r["scene"] == "collapse_2d" and r["aspect"] == 2.0 and r["exchange_every"] == 10
            and r.get("seed", bench.REFERENCE_SEED) == bench.REFERENCE_SEED] == [new[0]]
    # other intervals, packings, aspects and scenes stay as they were measured
    for r in kept[0], kept[2], kept[3], kept[4], kept[6]:
        assert r in merged
    # the silo's old failure went with its new row; the 3D collapse's, not rerun, stays
    assert kept[5] not in merged
    assert len(merged) == len(kept) - 2 + len(new)


def test_means_over_packings_are_the_rows_means_and_need_two_packings():
    rows = [collapse(seed=bench.REFERENCE_SEED, every=1, runout=-0.06), collapse(seed=2, every=1, runout=-0.02),
            collapse(seed=3, every=1, runout=+0.02), collapse(seed=bench.REFERENCE_SEED, every=10, runout=0.04)]
    for r, dem, overlap, fill in zip(rows, (4.0, 4.2, 4.4, 4.0), (0.01, 0.02, 0.06, 0.0), (0.1, 0.2, None, 0.0)):
        r["dem_value"], r["overlap"], r["fill_work"] = dem, overlap, fill
    lines = bench.mean_table(rows)
    body = [line for line in lines if line.startswith("| collapse_2d")]
    assert len(body) == 1, "every 10 has one packing: no mean"
    cells = [c.strip() for c in body[0].strip("|").split("|")]
    assert cells[2] == f"{bench.REFERENCE_SEED}, 2, 3"
    # the mean, its standard error over the packings (0.04 / sqrt 3), the DEM's spread (0.2 / 4.2)
    assert cells[5] == "-2.0 % ± 2.3 %"
    assert cells[10] == "3.0 %"
    assert cells[11] == "15.0 %", "the fill work's mean over the rows that have it"
    assert cells[12] == "4.8 %"
    assert bench.mean_table(rows[3:]) == []


@pytest.mark.parametrize("seed, floor", [(bench.REFERENCE_SEED, bench.OTHER_SEED), (2, bench.REFERENCE_SEED),
                                         (3, bench.REFERENCE_SEED)])
def test_each_packing_has_another_packing_for_its_noise_floor(seed, floor):
    assert bench.floor_seed(seed) == floor != seed


def silo(seed, rate, silo_name=None, date="old") -> dict:
    r = dict(scene="silo_2d", aspect=None, seed=seed, exchange_every=10, oracle_every=100, rate_error=rate,
             steps_ratio=None, noise_floor=0.005, date=date)
    if silo_name is not None:
        r["silo"] = silo_name
    return r


def test_the_deep_silo_stands_beside_the_shallow_one_it_does_not_replace():
    ref = bench.REFERENCE_SEED
    shallow = [silo(ref, 0.03), silo(2, 0.05)]          # written before rows named their silo
    deep = [silo(ref, -0.02, "deep", "new"), silo(2, -0.04, "deep", "new")]
    merged = bench.merge(shallow, deep)
    assert merged == shallow + deep
    # a rerun of the deep silo replaces the deep rows only
    again = [silo(ref, -0.01, "deep", "newer")]
    assert bench.merge(merged, again) == shallow + deep[1:] + again
    means = {line.split("|")[1].strip(): line for line in bench.mean_table(merged) if line.startswith("| silo_2d")}
    assert set(means) == {f"silo_2d {bench.SILO_DEFAULT}", f"silo_2d {bench.SILO_BEFORE}"}
    assert means["silo_2d deep"].split("|")[8].strip() == "-3.0 % ± 1.0 %"
    assert means["silo_2d shallow"].split("|")[8].strip() == "+4.0 % ± 1.0 %"


def test_a_variant_of_the_coupling_stands_beside_the_defaults_it_does_not_replace():
    ref = bench.REFERENCE_SEED
    defaults = [silo(ref, -0.03, "deep"), silo(2, -0.05, "deep")]
    variant = {"hfill": 0.1}
    filled = [dict(silo(ref, -0.01, "deep", "new"), hybrid_vars=variant),
              dict(silo(2, +0.03, "deep", "new"), hybrid_vars=variant)]
    merged = bench.merge(defaults, filled)
    assert merged == defaults + filled
    # a rerun of the variant replaces its own rows only; another value of it is another variant
    again = [dict(silo(ref, 0.0, "deep", "newer"), hybrid_vars=variant)]
    assert bench.merge(merged, again) == defaults + filled[1:] + again
    other = [dict(silo(ref, 0.0, "deep", "newer"), hybrid_vars={"hfill": 0.3})]
    assert bench.merge(merged, other) == merged + other
    means = {line.split("|")[1].strip(): line for line in bench.mean_table(merged) if line.startswith("| silo_2d")}
    assert set(means) == {"silo_2d deep", "silo_2d deep (hfill 0.1)"}
    assert means["silo_2d deep"].split("|")[8].strip() == "-4.0 % ± 1.0 %"
    assert means["silo_2d deep (hfill 0.1)"].split("|")[8].strip() == "+1.0 % ± 2.0 %"
    assert bench.variant_name(variant) == "_hfill0.1" and bench.variant_name({}) == ""


def test_hybrid_vars_are_deck_variables_of_the_hybrid_twin():
    assert bench.hybrid_vars_option("hfill=0.1,hsupport=0,hpic=regime") == {"hfill": 0.1, "hsupport": 0,
                                                                           "hpic": "regime"}
    assert bench.hybrid_vars_option("") == {}
    for bad in ("fill=0.1", "hfill", "hfill="):
        with pytest.raises(Exception, match="NAME=VALUE"):
            bench.hybrid_vars_option(bad)


def test_a_collapse_variants_noise_floor_is_the_runouts_as_the_defaults_is():
    ref = bench.REFERENCE_SEED
    rows = [collapse(seed=ref, floor=0.005), collapse(seed=2, floor=-0.005)]
    rows += [dict(r, hybrid_vars={"hfill": "auto"}) for r in rows]
    for r in rows:
        r["noise_floor"] = 0.013    # the surface's floor, which the means must not show as the runout's
    lines = [line for line in bench.mean_table(rows) if line.startswith("| collapse_2d")]
    assert len(lines) == 2 and "(hfill auto)" in lines[1]
    for line in lines:
        assert line.rstrip(" |").endswith("+0.5 %, -0.5 %"), line


def test_compaction_is_the_material_low_in_the_silo_over_the_dems_in_the_window():
    import numpy as np

    def state(t, low_mass):    # one body at 10 d, one at 100 d (above the measured height), one below the floor
        return dict(t=t, y=np.array([10 * bench.D, 100 * bench.D, -bench.D]), m=np.array([low_mass, 5.0, 7.0]))
    dem = [state(t, 1.0) for t in (0.0, 0.25, 0.5, 0.75, 1.0)]
    hyb = [state(t, 1.1 if 0.2 <= t <= 0.8 else 3.0) for t in (0.1, 0.3, 0.6, 0.9)]    # outside the window: ignored
    assert bench.compaction(hyb, dem) == pytest.approx(0.1)
    assert bench.compaction(dem, dem) == pytest.approx(0.0)
    assert np.isnan(bench.compaction([state(0.95, 1.0)], dem))
    assert np.isnan(bench.compaction([], dem))


def test_the_overlap_is_the_fix_entrys_mean_while_there_are_points(tmp_path):
    log = tmp_path / "log.lammps"
    log.write_text("Step Time f_couple[3] f_couple[34]\n"
                   "0 0 0 0\n10 0.001 40 0.02\n20 0.002 40 0.04\n"
                   "Loop time of 1.0 on 2 procs for 20 steps with 100 atoms\n"
                   "Step Time f_couple[3] f_couple[34]\n20 0.002 40 0.04\n30 0.003 0 0\n")
    assert bench.overlap(log) == pytest.approx(0.03)
    old = tmp_path / "old.lammps"    # a fix before the entry
    old.write_text("Step Time f_couple[3]\n0 0 40\n")
    assert bench.overlap(old) is None


def test_the_fill_work_is_the_fix_entrys_last_over_the_energy_released(tmp_path):
    log = tmp_path / "log.lammps"
    log.write_text("Step Time f_couple[19] f_couple[35]\n"
                   "0 0 10.0 0\n10 0.001 9.0 0.25\n"
                   "Loop time of 1.0 on 2 procs for 10 steps with 100 atoms\n"
                   "Step Time f_couple[19] f_couple[35]\n10 0.001 9.0 0.25\n20 0.002 6.0 0.5\n")
    assert bench.fill_work(log) == pytest.approx(0.5 / 4.0)
    gained = tmp_path / "gained.lammps"    # a run that released nothing has no share
    gained.write_text("Step Time f_couple[19] f_couple[35]\n0 0 1.0 0\n10 0.001 1.0 0.1\n")
    assert bench.fill_work(gained) is None
    old = tmp_path / "old.lammps"
    old.write_text("Step Time f_couple[19]\n0 0 1.0\n")
    assert bench.fill_work(old) is None


def test_the_ledger_figures_are_its_closure_and_the_guards_largest_share(tmp_path):
    ledger = " ".join(f"f_couple[{k}]" for k in range(19, 30))

    def row(step, total, residual, share=None):    # total 19 with the start in 20, residual 29
        return " ".join(map(str, [step, step * 1e-4, total, total] + [0.0] * 8 + [residual]
                            + ([] if share is None else [share]))) + "\n"

    log = tmp_path / "log.lammps"    # two runs; the guard's share is the largest the fix reported
    log.write_text(f"Step Time {ledger} f_couple[36]\n" + row(0, 10.0, 0.0, 0.0) + row(10, 10.0, 1e-14, 0.004)
                   + "Loop time of 1.0 on 2 procs for 10 steps with 100 atoms\n"
                   + f"Step Time {ledger} f_couple[36]\n" + row(10, 10.0, 1e-14, 0.004) + row(20, 10.0, -3e-14, 0.003))
    got = bench.ledger(log)
    assert got["guard_share"] == pytest.approx(0.004)
    assert got["ledger_closure"] == pytest.approx(3e-15)
    old = tmp_path / "old.lammps"    # a fix before the guard's entry
    old.write_text(f"Step Time {ledger}\n" + row(0, 10.0, 0.0) + row(10, 10.0, 1e-14))
    assert bench.ledger(old)["guard_share"] is None


def test_a_hybrid_run_that_fails_is_its_own_row_and_the_scenes_other_rows_stay(monkeypatch, tmp_path):
    """silo_2d over two packings whose second hybrid stops (as the fix's energy guard stops a run):
    the first packing's row is measured, the second is a row that names its run and the run's
    ERROR line; merging it replaces only that run's kept row, and a kept failure of one run goes
    only when that run is measured again."""
    guard = ("ERROR: Fix hybrid/mpm: the coupling made 14.38 J (J/m in 2D) of energy between t = 0.3 s and "
             "t = 0.34 s (/work/fix_hybrid_mpm.cpp:402)")

    def run_dem_silo(out, seed, hybrid_vars=None, **kw):
        if hybrid_vars and seed == 2:
            raise bench.RunFailed(f"hybrid failed in the discharge (1): mpirun ...\nmpm_solver: error: LAMMPS "
                                  f"stopped the coupled run\n{guard}\nLast command: run 1900 post no")
        return SimpleNamespace(rate=1.0 if hybrid_vars is None else 0.98, grains=4920, wall_time=10.0)

    for name, value in dict(run_dem_silo=run_dem_silo, dem_states=lambda out: None, frame_every=lambda out, e: 1,
                            hybrid_states=lambda out: (None, None), compaction=lambda a, b: 0.0,
                            rate_ratio_se=lambda a, b: 0.01, ledger=lambda log: dict(ledger_closure=0.0, guard_share=0.002),
                            overlap=lambda log: None,
                            fill_work=lambda log: None).items():
        monkeypatch.setattr(bench, name, value)
    rows = bench.silo_2d(tmp_path, 1, False, [(10, 100)], [bench.REFERENCE_SEED, 2])
    good, bad = rows
    assert "failed" not in good and good["rate_error"] == pytest.approx(-0.02)
    assert bad["failed"] == guard and (bad["seed"], bad["exchange_every"], bad["oracle_every"]) == (2, 10, 100)
    assert not bench.scene_failed(bad)
    args = SimpleNamespace(np_=1, out=tmp_path / "report.md", quick=False, scenes="silo_2d", exchanges="10",
                           oracles="100", seeds=f"{bench.REFERENCE_SEED},2", silo="deep", hybrid_vars=[])
    bench.write(args, rows)
    report = args.out.read_text()
    assert f"| silo_2d deep | 4920 |  | {bench.REFERENCE_SEED} | 10 | 100 | " in report
    assert (f"silo_2d deep, packing 2, every 10, oracle every 100: the hybrid failed (not in the means): "
            f"{guard}") in report

    kept = [silo(bench.REFERENCE_SEED, 0.01, "deep"), silo(2, 0.03, "deep"), silo(3, 0.04, "deep")]
    merged = bench.merge(kept, rows)
    assert kept[2] in merged, "a packing not rerun stays"
    assert kept[1] not in merged and bad in merged, "the failure replaces its own run's old row"
    rerun = [silo(2, -0.01, "deep", "new")]
    assert bench.merge(merged, rerun) == [r for r in merged if r is not bad] + rerun
    assert bad in bench.merge(merged, [silo(3, 0.0, "deep", "new")]), "another run's rerun keeps the failure"


def test_every_auto_is_an_exchange_interval_at_the_default_oracle_and_sorts_after_the_numbers():
    """The decks' default with adaptive zones is the fix's every auto; the fix rounds the oracle's steps
    up to a multiple of the interval it chooses, so auto runs at the default oracle interval as given."""
    pairs = bench.numerics([bench.exchange_interval(v) for v in "1,20,auto".split(",")], [300])
    assert pairs == [(1, 100), (20, 100), ("auto", 100), (bench.EXCHANGE_DEFAULT, 300)]
    assert bench.EXCHANGE_DEFAULT == "auto"
    with pytest.raises(ValueError):
        bench.exchange_interval("automatic")
    order = sorted(["auto", 20, 1, 5], key=bench.interval_order)
    assert order == [1, 5, 20, "auto"]
