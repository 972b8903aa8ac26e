"""bench/scale_speed.py: what it refuses before running anything, and how its rows at other depths
reach the JSON, the report and the plot.

The bench itself is not a test (its runs take hours); a refused invocation must fail at once with the
reason (not after hours of runs), and a row measured at another depth must not replace or hide the
row at the fix's depth.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
import scale_speed  # noqa: E402


def bench(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(REPO / "bench" / "scale_speed.py"), *args],
                          capture_output=True, text=True, timeout=120)


def test_depths_only_without_depths_is_refused_with_the_fix(tmp_path):
    done = bench("--collapse-sizes", "50", "--collapse-depths-only", "--out", str(tmp_path / "r.md"))
    assert done.returncode == 2
    assert "--collapse-depths 9" in done.stderr
    assert not (tmp_path / "r.json").exists()


def test_depths_only_and_touch_only_are_one_choice(tmp_path):
    done = bench("--collapse-depths", "9", "--collapse-depths-only", "--collapse-touch-only",
                 "--out", str(tmp_path / "r.md"))
    assert done.returncode == 2
    assert "not allowed with argument" in done.stderr


@pytest.mark.parametrize("flag, value", [("--collapse-every", "auto"), ("--collapse-every", "0"),
                                         ("--collapse-depths", "9d")])
def test_a_bad_depth_or_interval_is_refused_before_any_run(tmp_path, flag, value):
    done = bench("--sizes", "", "--silo3d-sizes", "", "--collapse-sizes", "50", flag, value,
                 "--out", str(tmp_path / "r.md"))
    assert done.returncode == 2
    assert "--collapse-every" in done.stderr and "--collapse-depths" in done.stderr
    assert not (tmp_path / "r.json").exists()


@pytest.mark.parametrize("flag, value, reason", [("--depths", "12d", "'12d' is not a number"),
                                                 ("--surface-depths", "-3", "'-3' is not positive"),
                                                 ("--every", "often", "'often' is not a whole number"),
                                                 ("--sizes", "40,9.5", "'9.5' is not a whole number")])
def test_a_bad_silo_value_is_refused_by_its_option(tmp_path, flag, value, reason):
    done = bench("--silo3d-sizes", "", "--collapse-sizes", "", flag, value, "--out", str(tmp_path / "r.md"))
    assert done.returncode == 2
    assert f"{flag} takes" in done.stderr and reason in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "r.json").exists()


def test_lists_keep_auto_only_where_it_is_allowed():
    assert scale_speed.parse_list("20, auto,40", int, auto=True) == [20, "auto", 40]
    assert scale_speed.parse_list("9,12.5", float) == [9.0, 12.5]
    assert scale_speed.parse_list("") == []
    with pytest.raises(ValueError, match="'auto' is not a whole number"):
        scale_speed.parse_list("auto", int)


def test_render_without_its_json_names_the_missing_file(tmp_path):
    done = bench("--render", "--out", str(tmp_path / "r.md"))
    assert done.returncode == 2
    assert str(tmp_path / "r.json") in done.stderr
    assert "Traceback" not in done.stderr


def collapse_row(depth, wall: float, runout: float, touch=1) -> dict:
    """A collapse row as run_collapse writes it (the fields the report and the plot read)."""
    return dict(scene="collapse_2d", grains=20759, width_d=100, height_d=200, orifice_d=None, error=0.02,
                runout_error=runout, steps_ratio=0.96, cores=2, lammps_ranks=2, mpm_threads=2, hcell="0",
                interleaved=True, speedup=307.0 / wall, cpu_speedup=307.0 / wall, predicted_speedup=300.0 / wall,
                dem_wall_s=307.0, hybrid_wall_s=wall, continuum_share=0.7, points_max=2000, coupling_s=20.0,
                mpm_wait_s=5.0, rezone_s=8.0, ledger_running_fraction=0.5, share_t=[0.0, 1.0],
                share=[0.0, 0.7], touch=touch, depth_d=depth, date="2026-12-06 00:00 UTC", pinned=False)


def test_depth_rows_are_kept_apart_and_each_gets_its_report_line(tmp_path):
    rows = [collapse_row(None, 148.0, 0.055), collapse_row(9.0, 116.0, 0.014), collapse_row(12.0, 140.0, 0.034),
            collapse_row(None, 760.0, -0.012, touch=None)]
    path = tmp_path / "scale_speed.json"
    scale_speed.save(path, rows, date="2026-12-06 00:00 UTC", np=2, command="test")
    saved = json.loads(path.read_text())
    # the untouched row at the fix's zones is the row; the touched ones are variants
    assert [r["touch"] for r in saved["rows"]] == [None]
    assert sorted((r["depth_d"] or 0) for r in saved["depth_front"]) == [0, 9.0, 12.0]
    assert scale_speed.load(path)[1] == [rows[3], *rows[:3]]
    lines = [line for line in scale_speed.table(rows) if line.startswith("| collapse_2d")]
    assert len(lines) == 4
    nine = next(line for line in lines if "depth 9" in line)
    assert "2.65x" in nine and "+1.4%" in nine
    # the fourth panel draws the touched rows against their wall time, the fix's depth among them
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    scale_speed.collapse_front(rows, ax)
    runout_line = ax.lines[0]
    assert list(runout_line.get_xdata()) == [116.0, 140.0, 148.0]
    assert list(runout_line.get_ydata()) == pytest.approx([1.4, 3.4, 5.5])
    labels = sorted(t.get_text() for t in ax.texts)
    assert labels == ["depth 12 d", "depth 3 cells", "depth 9 d"]
    plt.close(fig)


def test_collapse_hybrids_combine_depths_and_exchange_intervals():
    d = scale_speed.D
    runs = scale_speed.collapse_hybrids(100, "0", zones=False, touch=False, depths=(9.0, 12.0), everies=(20,))
    assert [name for name, *_ in runs] == ["hybrid_c100_touch1_depth9", "hybrid_c100_touch1_depth12",
                                           "hybrid_c100_touch1_depth9_every20", "hybrid_c100_touch1_depth12_every20"]
    name, hvars, touch, depth, every = runs[2]
    assert hvars == {"hybrid": 2, "hcell": "0", "htouch": 1, "hdepth": pytest.approx(9 * d), "hevery": 20}
    assert (touch, depth, every) == (1, 9.0, 20)
    # without depths the intervals run at the fix's depth; zones and touch add the two defaults first
    runs = scale_speed.collapse_hybrids(50, "0", zones=True, touch=True, everies=(40,))
    assert [(name, hvars.get("htouch"), hvars.get("hdepth"), hvars.get("hevery")) for name, hvars, *_ in runs] == [
        ("hybrid_c50", None, None, None), ("hybrid_c50_touch1", 1, None, None),
        ("hybrid_c50_touch1_every40", 1, None, 40)]


def test_the_front_joins_only_the_rows_of_one_dem_run(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    today = [collapse_row(9.0, 116.0, 0.014), dict(collapse_row(9.0, 100.0, 0.02), every=20)]
    other_day = [collapse_row(None, 148.0, 0.055), collapse_row(12.0, 140.0, 0.034)]
    for r in other_day:
        r["date"], r["dem_wall_s"] = "2026-12-05 14:47 UTC", 299.0
    alone = [dict(collapse_row(9.0, 746.0, 0.016), width_d=200, dem_wall_s=3336.0)]    # one hybrid: a point
    fig, ax = plt.subplots()
    scale_speed.collapse_front(today + other_day + alone, ax)
    runout_lines = [line for line in ax.lines if line.get_marker() == "o"]
    assert sorted(list(line.get_xdata()) for line in runout_lines) == [[100.0, 116.0], [140.0, 148.0], [746.0]]
    dem_marks = sorted(line.get_xdata()[0] for line in ax.lines if line.get_marker() == "s")
    assert dem_marks == [299.0, 307.0, 3336.0]
    assert "depth 9 d, exchange every 20" in [t.get_text() for t in ax.texts]
    plt.close(fig)
    assert "exchange every 20" in next(line for line in scale_speed.table(today) if "every" in line)


def test_another_packing_is_a_row_of_its_own():
    """Rows of two packings of one scene are two rows (a rerun with --seed 2 once replaced the
    default packing's row); a saved row without a seed is the default packing's."""
    row = dict(scene="collapse_2d", width_d=100, height_d=200, cores=2, pinned=False, depth_d=9, touch=1)
    assert scale_speed.row_key(dict(row, seed=2)) != scale_speed.row_key(dict(row, seed=scale_speed.DEFAULT_SEED))
    assert scale_speed.row_key(row) == scale_speed.row_key(dict(row, seed=scale_speed.DEFAULT_SEED))
    assert scale_speed.row_key(dict(row, depth_d=12)) != scale_speed.row_key(row)


def test_the_model_counts_a_grains_neighbours_in_lammpss_pair_share():
    """A hybrid whose grains have half the DEM's neighbours each costs, per grain-step, the DEM's
    non-Pair share plus half its Pair share; LAMMPS's per-run counts are read from both logs."""
    def run(loop, steps, atoms, pair, per_atom=None):    # LAMMPS's end-of-run lines
        return (f"Loop time of {loop} on 2 procs for {steps} steps with {atoms} atoms\n\n"
                "MPI task timing breakdown:\n"
                "Section |  min time  |  avg time  |  max time  |%varavg| %total\n"
                "---------------------------------------------------------------\n"
                f"Pair    | 1.0        | {pair}     | 1.0        |   0.0 | 50.00\n\n"
                + ("" if per_atom is None else f"Total # of neighbors = 1\nAve neighs/atom = {per_atom}\n"))
    dem = run(10.0, 100, 1000, 6.0, 3.0) + run(10.0, 100, 1000, 6.0, 3.0)
    # a run without a neighbour count (a run 0) counts its time, not the next run's neighbours
    hybrid = run(0.0, 1, 500, 0.0) + run(2.0, 200, 100, 0.4, 1.5)
    factor, per_grain = scale_speed.neighbour_factor(dem, hybrid)
    assert per_grain == pytest.approx([3.0, 1.5])
    assert factor == pytest.approx(0.4 + 0.6 * 0.5)
    assert scale_speed.neighbour_factor(dem, "no run here")[0] == 1.0
