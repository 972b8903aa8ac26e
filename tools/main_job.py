#!/usr/bin/env python3
"""The main job: the default scene, a planar granular column collapse (aspect
ratio 2), with its comparison output.

The collapse runs as pure LAMMPS DEM (the reference, input_decks/column_collapse/
dem_2d.lmp) and as pure MPM with each constitutive model; each is compared with
the DEM (final surface) and with the published runout laws (DESIGN.md section 6).
When the coupled DEM-MPM fix lands, the hybrid joins the table.

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
from mpm_results import load_run, surface_profile  # noqa: E402

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
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--no-dem", action="store_true", help="skip the pure LAMMPS DEM reference")
    args = ap.parse_args()
    if not SOLVER.exists():
        sys.exit(f"main_job: {SOLVER} is not built; run tools/setup.sh")
    args.out.mkdir(parents=True, exist_ok=True)

    dem = None
    if not args.no_dem:
        print("main_job: pure LAMMPS DEM reference (the settled column is built once and cached)", flush=True)
        dem = run_dem(aspect=args.aspect, width=0.1, np_=args.threads, out=args.out / "dem")
        print(dem.summary(), flush=True)
    results = [run_model(m, args.aspect, args.cell, args.out, args.threads) for m in ("drucker_prager", "mu_i")]
    lo, hi = published_runout_range(args.aspect)
    height0 = args.aspect * 0.1

    def against_law(runout: float) -> str:
        return "yes" if lo <= runout <= hi else f"no ({(runout - np.clip(runout, lo, hi)) / hi:+.0%})"

    lines = [f"# Column collapse, aspect ratio {args.aspect:g}, L0 = 0.1 m", "",
             f"Published runout (Lf - L0)/L0 for a = {args.aspect:g}: {lo:.2f} to {hi:.2f} "
             "(Lube et al. 2005; Lajeunesse et al. 2005). Surface error: RMS difference of the final "
             "surface height from the DEM deposit's, from the wall to the farther front, as a fraction of the "
             "column height H0.", "",
             "| run | (Lf - L0)/L0 | within published range | surface error vs DEM | final height / L0 | size | wall s |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    if dem is not None:
        lines.append(f"| LAMMPS DEM (reference) | {dem.runout:.2f} | {against_law(dem.runout)} | - | "
                     f"{dem.final_height / 0.1:.2f} | {dem.grains} grains | {dem.wall_time:.1f}"
                     f"{' (incl. column preparation)' if dem.prepared else ''} |")
    for r in results:
        error = "-"
        if dem is not None:
            spacing = args.cell / 2  # 2 x 2 points per cell (ColumnCollapse)
            mpm_surface = points_surface(r["positions"], spacing, 2 * 0.002)
            r["surface_error"] = surface_error(mpm_surface, np.array(dem.profile).T, height0)
            error = f"{r['surface_error']:.1%}"
        lines.append(f"| MPM {r['model']} | {r['runout']:.2f} | {against_law(r['runout'])} | {error} | "
                     f"{r['height']:.2f} | {r['points']} points, {r['steps']} steps | {r['wall']:.1f} |")
    report = args.out / "report.md"
    report.write_text("\n".join(lines) + "\n")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.2))
    if dem is not None:
        dem_x, dem_h = np.array(dem.profile).T
        ax.plot(dem_x / 0.1, dem_h / 0.1, "k", lw=2, label="LAMMPS DEM")
    for r in results:
        heights, edges = surface_profile(r["positions"], bins=80, return_edges=True)
        centres = 0.5 * (edges[:-1] + edges[1:])
        ax.plot(centres / r["width"], heights / r["width"], label=f"MPM {r['model']}")
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
