#!/usr/bin/env python3
"""The 2D silo as pure MPM against pure LAMMPS DEM, side by side in one invocation: the DEM
discharge (tools/dem_silo.py, from its cached settled silo) and the pure-MPM silo of the same
size (tools/mpm_silo.py: the calibrated continuum, Drucker-Prager and mu(I), cells of several
grain sizes), each run's steady rate over the same window (hgtools.discharge.fit_rate) and its
wall time. The MPM runs use --threads OpenMP threads, by default as many as the DEM's LAMMPS
ranks, so both get the same cores.

What it measures: how far a continuum alone is from the grains at the orifice, as the cell
shrinks towards the grain size (the hybrid keeps the orifice's grains discrete instead;
bench/results/scale_speed.md).

Usage: bench/mpm_silo.py [--width-d 40] [--cells 2,1] [--models drucker_prager,mu_i] [--np 2]
Writes bench/results/mpm_silo.{json,md} (the notes below the marker kept).
"""
from __future__ import annotations

import argparse
import json
import sys
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(REPO / "tools"), str(REPO / "bench")]
from dem_silo import run_dem_silo  # noqa: E402
from hgtools.report import write_report  # noqa: E402
from mpm_silo import MpmSilo, run as run_mpm_silo  # noqa: E402
from scale_speed import D, DEPTH, ORIFICE, RESULTS, silo_size  # noqa: E402 (the same silo, in grain diameters)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--width-d", type=int, default=40)
    ap.add_argument("--cells", default="2,1", help="MPM cells in grain diameters")
    ap.add_argument("--models", default="drucker_prager,mu_i")
    ap.add_argument("--np", dest="np_", type=int, default=2, help="LAMMPS ranks of the DEM run")
    ap.add_argument("--threads", type=int, default=0, help="the MPM runs' OpenMP threads (0: as --np)")
    ap.add_argument("--tdis", type=float, default=0.4)
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--work", type=Path, default=REPO / "runs" / "mpm_silo")
    ap.add_argument("--out", type=Path, default=RESULTS / "mpm_silo.md")
    a = ap.parse_args()
    n, threads = a.width_d, a.threads or a.np_
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    size = silo_size(n)
    dem = run_dem_silo(**size, np_=a.np_, seed=a.seed, tdis=a.tdis, fstop=0.9, out=a.work / "dem", timeout=4 * 3600)
    rows = [dict(form="dem", cell_d=None, rate=dem.rate, rate_error=0.0, wall_s=dem.wall_time, speedup=1.0,
                 grains=dem.grains, cores=a.np_)]
    for model in a.models.split(","):
        for cell in (float(c) for c in a.cells.split(",")):
            silo = MpmSilo(**size, model=model, cell=cell * D, tdis=a.tdis)
            res = run_mpm_silo(silo, a.work / f"mpm_{model}_{cell:g}d", threads=threads, timeout=4 * 3600)
            rows.append(dict(form=f"mpm_{model}", cell_d=cell, rate=res["rate"], rate_error=res["rate"] / dem.rate - 1,
                             rate_halves=[res["rate_first"], res["rate_second"]], wall_s=res["wall_time"],
                             speedup=dem.wall_time / res["wall_time"], points=res["points_left"], cores=threads))
            print(f"{model}, cell {cell:g} d: rate {res['rate']:.3f} ({rows[-1]['rate_error']:+.1%}), "
                  f"{res['wall_time']:.0f} s", flush=True)
    command = (f"bench/mpm_silo.py --width-d {n} --cells {a.cells} --models {a.models} --np {a.np_} "
               f"--threads {threads} --tdis {a.tdis} --seed {a.seed}")
    a.out.with_suffix(".json").write_text(json.dumps(dict(date=stamp, command=command, width_d=n, height_d=DEPTH * n,
                                                          orifice_d=ORIFICE, rows=rows), indent=1))
    table = ["# The 2D silo as pure MPM against pure LAMMPS DEM", "",
             f"`{command}`, {stamp}: W = {n} d, H = {DEPTH * n} d, D = {ORIFICE} d, d = {D * 1e3:g} mm, "
             f"{dem.grains} disks; {a.tdis:g} s of discharge, the steady rate over the DEM's window. The MPM runs "
             "start from the fill at rest (geostatic) with the calibrated continuum (input_decks/materials/"
             "disks_2d.toml) and the grains' wall friction; side by side on a 2-core machine that may be shared.", "",
             "| form | cell (d) | rate (kg/s/m) | error vs DEM | halves of the window | wall s | speedup over DEM | "
             "cores |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        halves = ", ".join(f"{h:.2f}" for h in r.get("rate_halves", []))
        cell = "" if r["cell_d"] is None else f"{r['cell_d']:g}"
        table.append(f"| {r['form']} | {cell} | {r['rate']:.3f} | {r['rate_error']:+.1%} | {halves} | "
                     f"{r['wall_s']:.0f} | {r['speedup']:.2f}x | {r['cores']} |")
    write_report(a.out, "\n".join(table))
    print("\n".join(table))
    return 0


if __name__ == "__main__":
    sys.exit(main())
