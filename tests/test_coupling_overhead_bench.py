"""bench/coupling_overhead.py: how it reads a LAMMPS log and what it makes of the runs.

The bench itself is not a test (it times runs on a shared machine); its reading of the logs is, since
a figure read from the wrong run or the wrong case is silently wrong.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import coupling_overhead  # noqa: E402


def fix_block(exchange: float, wait: float, apply: float, coupling: float) -> str:
    """The fix's timing block as it prints it at the end of a run (coupler/dem_run_log.cpp)."""
    rows = [("Exchange", exchange), ("MPM wait", wait), ("Apply", apply), ("Rezone", 0.0), ("Oracle", 0.0),
            ("Output", 0.0), ("Coupling", coupling)]
    lines = ["fix hybrid/mpm timing breakdown (20 exchanges, 1 rezones):", "",
             "Section |  min time  |  avg time  |  max time  |%varavg| %total", "-" * 62]
    # min and max differ from the mean so that reading the wrong column shows
    lines += [f"{name:<8}| {0.5 * t:<11.5g}| {t:<11.5g}| {2 * t:<11.5g}|   0.0 |  1.00" for name, t in rows]
    return "\n".join(lines) + "\n"


def lammps_run(loop: float, steps: int, pair: float, modify: float) -> str:
    return (f"Loop time of {loop} on 1 procs for {steps} steps with 1000 atoms\n\n"
            "98.5% CPU use with 1 MPI tasks x 1 OpenMP threads\n\n"
            "Section |  min time  |  avg time  |  max time  |%varavg| %total\n"
            f"Pair    | {pair}     | {pair}     | {pair}     |   0.0 | 70.00\n"
            f"Modify  | {modify}   | {modify}   | {modify}   |   0.0 | 20.00\n"
            "Other   |            | 0.01       |            |       |  1.00\n\n"
            "Total # of neighbors = 3000\n")


def test_the_fix_block_is_read_from_the_last_run_and_its_mean_column():
    warmup = fix_block(9.0, 9.0, 9.0, 27.0) + lammps_run(5.0, 100, 3.0, 1.0)
    timed = fix_block(0.05, 0.1, 0.04, 0.2) + lammps_run(2.0, 1000, 1.5, 0.4)
    r = coupling_overhead.parse_log(warmup + timed)
    assert r["steps"] == 1000 and r["loop_time"] == pytest.approx(2.0)
    assert r["fix_sections"]["Exchange"] == pytest.approx(0.05)
    assert r["fix_sections"]["MPM wait"] == pytest.approx(0.1)
    assert r["fix_sections"]["Coupling"] == pytest.approx(0.2)
    assert r["sections"]["Pair"] == pytest.approx(1.5)


def run(case: str, rep: int, steps: int, loop: float, fix: dict | None = None) -> dict:
    return {"case": case, "rep": rep, "steps": steps, "loop_time": loop, "step_s": loop / steps, "atoms": 1000,
            "disturbed": False, "sections": {"Pair": 0.7 * loop, "Modify": 0.2 * loop}, "cpu_use_percent": 99.0,
            "contacts": [2000.0], "neighbor_pairs": 3000, "thermo": {}, "fix_sections": fix or {"Output": 1e-4}}


def test_each_case_gets_its_own_runs_fix_ledger():
    """The uncoupled cases' logs have no fix block; a coupled case's ledger must come from its own runs
    whatever the order of the cases (once it came from the last case's, a DEM run: zeros)."""
    cases = [{"name": "np1_lammps", "np": 1, "couple": False, "trim": True, "every": 1},
             {"name": "np1_coupled_every10", "np": 1, "couple": True, "trim": True, "every": 10},
             {"name": "np1_coupled_every1", "np": 1, "couple": True, "trim": True, "every": 1},
             {"name": "np1_full_dem", "np": 1, "couple": False, "trim": False, "every": 1}]
    runs = []
    for rep in range(3):
        runs.append(run("np1_lammps", rep, 2000, 4.0))
        runs.append(run("np1_coupled_every10", rep, 2000, 4.4,
                        {"Exchange": 0.05, "MPM wait": 0.1, "Apply": 0.05, "Coupling": 0.22}))
        runs.append(run("np1_coupled_every1", rep, 2000, 6.0,
                        {"Exchange": 0.4, "MPM wait": 0.6, "Apply": 0.2, "Coupling": 1.2}))
        runs.append(run("np1_full_dem", rep, 2000, 8.0))
    s = coupling_overhead.summarize(cases, runs)
    every10, every1 = s["np1_coupled_every10"], s["np1_coupled_every1"]
    # 200 exchanges: (0.05 + 0.05) s of own work and 0.1 s of waiting
    assert every10["fix_work_ms_per_exchange"] == pytest.approx(0.5)
    assert every10["mpm_wait_ms_per_exchange"] == pytest.approx(0.5)
    assert every10["fix_share"] == pytest.approx(0.22 / 4.4)
    assert every1["fix_work_ms_per_exchange"] == pytest.approx(0.3)
    assert every1["fix_share"] == pytest.approx(0.2)
    assert every10["overhead"] == pytest.approx(0.1)
    assert "fix_share" not in s["np1_lammps"]
