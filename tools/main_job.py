#!/usr/bin/env python3
"""The main job: the default scene, a planar granular column collapse (aspect
ratio 2), with its comparison output.

The collapse runs as pure LAMMPS DEM (the reference, input_decks/column_collapse/
dem_2d.lmp), as the hybrid (the same deck with `hybrid 1`: lmp_hybrid + mpm_solver,
fix hybrid/mpm, from the same settled column) and as pure MPM with each constitutive
model; each is compared with the DEM (final surface, wall time) and with the published
runout laws (DESIGN.md section 6).

Writes <out>/report.md (table) and <out>/profiles.png (final surface profiles).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from column_collapse import (ColumnCollapse, normalised_runout, points_surface,  # noqa: E402
                             published_runout_range, surface_error)
from dem_collapse import run as run_dem  # noqa: E402
from column_collapse import combine_surfaces  # noqa: E402
from mpm_results import load_run  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SOLVER = REPO / "build" / "mpm_solver" / "mpm_solver"


def run_model(model: str, aspect: float, cell: float, out: Path, threads: int) -> dict:
    scene = ColumnCollapse(aspect=aspect, width=0.1, cell_size=cell, model=model, output_interval=0.05)
    work = out / model
    path = scene.write(work)
    summary = work / "summary.json"
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    print(f"main_job: {model}: running {path.name}", flush=True)
    start = time.perf_counter()
    subprocess.run([str(SOLVER), str(path), "--summary", str(summary)], check=True, env=env)
    wall = time.perf_counter() - start
    run = load_run(work / "output")
    final = run.frame(-1)
    figures = json.loads(summary.read_text())
    return {
        "model": model,
        "runout": normalised_runout(final["position"], scene.width, scene.cell_size),
        "height": float(np.max(final["position"][:, -1])) / scene.width,
        "points": figures["points"],
        "steps": figures["steps"],
        "wall": wall,
        "positions": final["position"],
        "width": scene.width,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "runs" / "main", help="output directory (default runs/main)")
    ap.add_argument("--aspect", type=float, default=2.0, help="column aspect ratio H0/L0 (default 2)")
    ap.add_argument("--cell", type=float, default=0.005, help="MPM cell size in m (default 0.005)")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                    help="LAMMPS ranks (DEM and hybrid alike) and MPM threads")
    args = ap.parse_args()
    if not SOLVER.exists():
        sys.exit(f"main_job: {SOLVER} is not built; run tools/setup.sh")
    args.out.mkdir(parents=True, exist_ok=True)
    width, d = 0.1, 0.002
    height0 = args.aspect * width

    print("main_job: pure LAMMPS DEM reference (the settled column is built once and cached)", flush=True)
    dem = run_dem(aspect=args.aspect, width=width, np_=args.threads, out=args.out / "dem")
    if dem.prepared:  # time the collapse alone, as the hybrid's, from the cached column
        print("main_job: the DEM column was prepared in this run; running the DEM collapse again from the cache "
              "so that its wall time compares with the hybrid's", flush=True)
        dem = run_dem(aspect=args.aspect, width=width, np_=args.threads, out=args.out / "dem")
    print(dem.summary(), flush=True)
    reference = np.array(dem.profile).T
    print("main_job: hybrid (lmp_hybrid + mpm_solver) from the same settled column", flush=True)
    hybrid = run_dem(aspect=args.aspect, width=width, np_=args.threads, out=args.out / "hybrid", hybrid_vars={})
    print(hybrid.summary(), flush=True)
    points = load_run(args.out / "hybrid" / "frames").frame(-1)
    hybrid_surface = combine_surfaces(np.array(hybrid.profile).T,
                                      points_surface(points["position"], width / 20, 2 * d))
    results = [run_model(m, args.aspect, args.cell, args.out, args.threads) for m in ("drucker_prager", "mu_i")]
    for r in results:
        r["surface"] = points_surface(r["positions"], args.cell / 2, 2 * d)  # 2 x 2 points per cell
    lo, hi = published_runout_range(args.aspect)

    def against_law(runout: float) -> str:
        return "yes" if lo <= runout <= hi else f"no ({(runout - np.clip(runout, lo, hi)) / hi:+.0%})"

    lines = [f"# Column collapse, aspect ratio {args.aspect:g}, L0 = {width:g} m", "",
             f"Published runout (Lf - L0)/L0 for a = {args.aspect:g}: {lo:.2f} to {hi:.2f} "
             "(Lube et al. 2005; Lajeunesse et al. 2005). Surface error: RMS difference of the final "
             "surface height from the DEM deposit's, from the wall to the farther front, as a fraction of the "
             "column height H0. Speedup: DEM wall time over the run's, measured side by side in this job "
             f"({args.threads} LAMMPS rank(s); the hybrid adds one MPM process). The hybrid turns the block "
             "x < L0/2, y < 0.7 L0 against the back wall (inside the collapse's static wedge) into continuum; "
             "its zones are fixed. Steps to rest: LAMMPS steps until the mean kinetic energy per grain is below the "
             "deck's rest threshold (the MPM runs a fixed time in its own steps); ms per step: LAMMPS's loop time "
             "over those steps.", "",
             "| run | (Lf - L0)/L0 | within published range | surface error vs DEM | final height / L0 | size | steps to rest | ms per step | wall s | speedup vs DEM |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
             f"| LAMMPS DEM (reference) | {dem.runout:.2f} | {against_law(dem.runout)} | - | "
             f"{dem.final_height / width:.2f} | {dem.grains} grains | {dem.steps} | {1e3 * dem.loop_time / dem.steps:.3f} | "
             f"{dem.wall_time:.1f} | 1 |"]
    error = surface_error(hybrid_surface, reference, height0)
    lines.append(f"| hybrid (LAMMPS + MPM) | {hybrid.runout:.2f} | {against_law(hybrid.runout)} | {error:.1%} | "
                 f"{max(hybrid.final_height, float(points['position'][:, 1].max())) / width:.2f} | "
                 f"{hybrid.grains} grains + {len(points['position'])} points | {hybrid.steps} | "
                 f"{1e3 * hybrid.loop_time / hybrid.steps:.3f} | {hybrid.wall_time:.1f} | "
                 f"{dem.wall_time / hybrid.wall_time:.2f} |")
    for r in results:
        r["surface_error"] = surface_error(r["surface"], reference, height0)
        lines.append(f"| MPM {r['model']} | {r['runout']:.2f} | {against_law(r['runout'])} | "
                     f"{r['surface_error']:.1%} | {r['height']:.2f} | {r['points']} points | {r['steps']} (MPM) | "
                     f"{1e3 * r['wall'] / r['steps']:.3f} | {r['wall']:.1f} | {dem.wall_time / r['wall']:.2f} |")
    report = args.out / "report.md"
    report.write_text("\n".join(lines) + "\n")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.2))
    ax.plot(reference[0] / width, reference[1] / width, "k", lw=2, label="LAMMPS DEM")
    ax.plot(hybrid_surface[0] / width, hybrid_surface[1] / width, "C3", lw=1.5, label="hybrid")
    for r in results:
        ax.plot(r["surface"][0] / width, r["surface"][1] / width, lw=1, label=f"MPM {r['model']}")
    ax.axvspan(1 + lo, 1 + hi, color="grey", alpha=0.2, label="published runout")
    ax.set_xlabel("x / L0")
    ax.set_ylabel("surface height / L0")
    ax.set_title(f"Column collapse, a = {args.aspect:g}: final surface")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "profiles.png", dpi=120)

    print("\n".join(lines))
    print(f"\nmain_job: report {report}, plot {args.out / 'profiles.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
