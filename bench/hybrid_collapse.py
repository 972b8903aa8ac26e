#!/usr/bin/env python3
"""Wall time of the hybrid column collapse against pure LAMMPS DEM, with the hybrid's error.

The planar collapse of the main job (a = 2, L0 = 0.1 m, about 5,200 disks;
input_decks/column_collapse/dem_2d.lmp) runs as pure DEM and as its hybrid twin (`hybrid 1`:
lmp_hybrid + mpm_solver, the block x < L0/2, y < 0.7 L0 against the back wall is continuum),
both from the same cached settled column, interleaved, `--repeat` times. For each run: wall
time, LAMMPS steps until the deposit is at rest, LAMMPS loop time per step, runout, and for
the hybrid the final-surface error against the DEM run of the same repetition (RMS over the
deposit, as a fraction of H0). Ratios are DEM over hybrid within a repetition.

Usage: bench/hybrid_collapse.py [--repeat 2] [--np 2] [--width 0.1]
Writes bench/results/hybrid_collapse.md and .json.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from column_collapse import combine_surfaces, points_surface, surface_error  # noqa: E402
from dem_collapse import run  # noqa: E402
from mpm_results import load_run  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--np", type=int, default=2, dest="np_", help="LAMMPS ranks, for both runs")
    ap.add_argument("--width", type=float, default=0.1, help="L0, m")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "hybrid_collapse.md")
    args = ap.parse_args()
    aspect, d = 2.0, 0.002
    rows = []
    with tempfile.TemporaryDirectory(prefix="hybrid_collapse_") as tmp:
        work = Path(tmp)
        run(aspect=aspect, width=args.width, d=d, np_=args.np_, out=work / "prepare")  # settles and caches the column
        for rep in range(args.repeat):
            dem = run(aspect=aspect, width=args.width, d=d, np_=args.np_, out=work / f"dem{rep}")
            hyb = run(aspect=aspect, width=args.width, d=d, np_=args.np_, out=work / f"hybrid{rep}", hybrid_vars={})
            points = load_run(work / f"hybrid{rep}" / "frames").frame(-1)["position"]
            surface = combine_surfaces(np.array(hyb.profile).T, points_surface(points, args.width / 20, 2 * d))
            error = surface_error(surface, np.array(dem.profile).T, aspect * args.width)
            rows.append(dict(
                repetition=rep, dem_wall=dem.wall_time, hybrid_wall=hyb.wall_time,
                dem_steps=dem.steps, hybrid_steps=hyb.steps,
                dem_ms_per_step=1e3 * dem.loop_time / dem.steps, hybrid_ms_per_step=1e3 * hyb.loop_time / hyb.steps,
                dem_runout=dem.runout, hybrid_runout=hyb.runout, surface_error=error,
                grains=dem.grains, hybrid_grains=hyb.grains, points=len(points),
                speedup=dem.wall_time / hyb.wall_time,
                per_step_ratio=(dem.loop_time / dem.steps) / (hyb.loop_time / hyb.steps)))
            print(f"repetition {rep}: DEM {dem.wall_time:.1f} s, hybrid {hyb.wall_time:.1f} s, "
                  f"surface error {error:.1%}", flush=True)
    med = lambda key: statistics.median(r[key] for r in rows)
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"# Hybrid column collapse against pure LAMMPS DEM ({when})", "",
             f"Planar collapse a = {aspect:g}, L0 = {args.width:g} m, {rows[0]['grains']} disks of d = {d} m; "
             f"{args.np_} LAMMPS rank(s) in both runs, the hybrid adds one MPM process (the machine has 2 cores). "
             f"The hybrid's continuum is the block x < L0/2, y < 0.7 L0 (fixed zones): {rows[0]['points']} points "
             f"for {rows[0]['grains'] - rows[0]['hybrid_grains']} grains. Runs interleaved, {args.repeat} repetitions. "
             f"Made by `bench/hybrid_collapse.py --repeat {args.repeat} --np {args.np_} --width {args.width:g}`.", "",
             "| repetition | DEM wall s | hybrid wall s | speedup (DEM / hybrid) | DEM steps to rest | hybrid steps | "
             "DEM ms/step | hybrid ms/step | per-step ratio | runout DEM | runout hybrid | hybrid surface error vs DEM |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        lines.append(f"| {r['repetition']} | {r['dem_wall']:.1f} | {r['hybrid_wall']:.1f} | {r['speedup']:.2f} | "
                     f"{r['dem_steps']} | {r['hybrid_steps']} | {r['dem_ms_per_step']:.3f} | "
                     f"{r['hybrid_ms_per_step']:.3f} | {r['per_step_ratio']:.2f} | {r['dem_runout']:.2f} | "
                     f"{r['hybrid_runout']:.2f} | {r['surface_error']:.1%} |")
    lines += ["", f"Median speedup {med('speedup'):.2f} (target for the hybrid method: >= 5 at a final-surface "
              f"error <= 5 % of H0), median per-step ratio {med('per_step_ratio'):.2f}, median surface error "
              f"{med('surface_error'):.1%}."]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
