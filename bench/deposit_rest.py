#!/usr/bin/env python3
"""Does the adaptive hybrid's deposit come to rest where the DEM's does (issue 14)?

Scene: the 2D column collapse, a = 2, L0 = n d (input_decks/column_collapse/dem_2d.lmp), as pure
LAMMPS DEM to rest and as its adaptive hybrid twin (`hybrid 2`, the fix's grid from the grains,
`hcell 0`) from the same cached column, the hybrid stopped `--after` seconds past the time the
DEM came to rest (deck variable tmax).

Measures, the DEM at rest:
- the stress ratio tau/p (the continuum's measure, tau = |dev sigma|/sqrt 2) of the deposit per
  cell of the hybrid's size (6 d), from each grain's contact stress (Love-Weber, deck variable
  stressout): median, 90th percentile, and the share of cells above the continuum's friction
  mu_s of the material file (which the Drucker-Prager cone holds: sin phi = mu_s in 2D);
- the median grain speed.
The hybrid over its frames after the DEM's rest time:
- its points: the share on the yield cone (tau/p >= 0.99 mu_s), the median tau/p, their mean
  velocity (mass-weighted) and how far they moved between the first and last of these frames;
- its grains' mean velocity (mass-weighted), hybrid (weight < 1) and discrete apart, and median
  speeds;
- the deck's rest measure: kinetic energy per grain over the rest threshold (1e-5 m g d), mean
  over the same window.

Usage: bench/deposit_rest.py [--np 2] [--width-d 100] [--after 0.7]
Writes bench/results/deposit_rest.json and deposit_rest.md (notes below the marker kept).
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from dem_collapse import END_RE, FORMS, run as run_collapse, settled  # noqa: E402
from hgtools import logs  # noqa: E402
from hgtools.grains import read_dump  # noqa: E402
from hgtools.materials import material_path, read_material  # noqa: E402
from hgtools.report import write_report  # noqa: E402
from mpm_results import load_run, read_grains  # noqa: E402

D = 0.002            # grain diameter, m (the deck's)
ASPECT = 2
SEED = 12345
CELL_D = 6           # the fix's cell from these grains (hcell 0), in d
EVERY = 10           # the hybrid's exchange interval, steps (deck variable hevery)
MATERIAL = "disks_2d"    # the deck's continuum (hmaterial)


def stress_ratio_2d(sxx, syy, sxy):
    """tau/p of 2D stresses (any common sign and scale: the ratio is the same)."""
    p = -0.5 * (sxx + syy)
    tau = np.sqrt(0.25 * (sxx - syy) ** 2 + sxy ** 2)
    return np.where(p > 0, tau / np.where(p > 0, p, 1.0), np.nan)


def deposit_stress(path: Path, cell: float, min_grains: int = 20) -> np.ndarray:
    """tau/p per cell of side `cell` holding at least min_grains grains: the sum of the grains'
    stress times volume over the cell (Love-Weber; the cell's area cancels in the ratio)."""
    g = read_dump(path)
    ix, iy = (g["x"] / cell).astype(int), (g["y"] / cell).astype(int)
    shape = (ix.max() + 1, iy.max() + 1)
    sums = [np.zeros(shape) for _ in range(3)]
    for s, col in zip(sums, ("c_grainstress[1]", "c_grainstress[2]", "c_grainstress[4]")):
        np.add.at(s, (ix, iy), g[col])
    count = np.zeros(shape)
    np.add.at(count, (ix, iy), 1)
    ratio = stress_ratio_2d(*sums)
    return ratio[(count >= min_grains) & np.isfinite(ratio)]


def mass_mean(mass, v):
    return (mass[:, None] * v).sum(axis=0) / mass.sum()


def window_frames(run, t_from: float) -> list[int]:
    """Indices of the hybrid's frames (an mpm_results Run) at or after t_from."""
    return [f.index for f in run.frames if f.time >= t_from]


def points_state(run, indices: list[int], mu_s: float) -> list[dict]:
    """Per frame: the points' share on the yield cone, median tau/p, mass-weighted mean velocity."""
    rows = []
    for i in indices:
        f = run.frame(i, ["position", "velocity", "mass", "stress"])
        s = f["stress"]
        ratio = stress_ratio_2d(s[:, 0, 0], s[:, 1, 1], s[:, 0, 1])
        rows.append(dict(time=float(f["time"]), points=len(f["mass"]), on_cone=float(np.mean(ratio >= 0.99 * mu_s)),
                         ratio_median=float(np.nanmedian(ratio)),
                         mean_v=mass_mean(f["mass"], f["velocity"][:, :2]).tolist(), position=f["position"][:, :2]))
    return rows


def points_drift(first: dict, last: dict) -> list[float]:
    """Mean velocity of the points from one frame to another (displacement to the nearest point
    of the earlier frame; points carry no IDs), m/s."""
    x0, x1 = first["position"], last["position"]
    near = np.array([np.argmin(((x0 - p) ** 2).sum(axis=1)) for p in x1])
    return ((x1 - x0[near]).mean(axis=0) / max(last["time"] - first["time"], 1e-12)).tolist()


def grains_state(run, indices: list[int]) -> list[dict]:
    """Per frame: mass-weighted mean velocity and median speed of the hybrid (weight < 1) and the
    discrete grains."""
    rows = []
    for i in indices:
        g = read_grains(run.path, i)
        row = dict(time=float(g["time"]))
        for name, sel in (("hybrid", g["weight"] < 1.0), ("discrete", g["weight"] >= 1.0)):
            v = g["velocity"][sel][:, :2]
            row[name] = dict(mean_v=mass_mean(g["mass"][sel], v).tolist() if sel.any() else [0.0, 0.0],
                             median_speed=float(np.median(np.hypot(v[:, 0], v[:, 1]))) if sel.any() else 0.0)
        rows.append(row)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--np", type=int, default=2, dest="np_", help="LAMMPS ranks, DEM and hybrid alike")
    ap.add_argument("--width-d", type=int, default=100, help="L0 in grain diameters")
    ap.add_argument("--after", type=float, default=0.7, help="the hybrid runs this long past the DEM's rest, s")
    ap.add_argument("--frame-every", type=float, default=0.05, help="the hybrid's frames, s apart")
    ap.add_argument("--work", type=Path, default=REPO / "runs" / "deposit_rest")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "deposit_rest.md")
    a = ap.parse_args()
    width = a.width_d * D
    mu_s = read_material(MATERIAL)["continuum"]["mu_s"]
    cache = settled(ASPECT, width, D, SEED, {})
    if not cache.cached():    # the settled column, once (cached for every later run)
        run_collapse(aspect=ASPECT, width=width, d=D, np_=a.np_, out=a.work / "prepare", seed=SEED, timeout=6 * 3600)
    common = dict(aspect=ASPECT, width=width, d=D, settled=str(cache.path), prep=0, seed=SEED)

    dem_out = a.work / "dem"
    dem_out.mkdir(parents=True, exist_ok=True)
    dem = FORMS.run("lammps", dict(common, out=str(dem_out), stressout=1), dem_out / "log.lammps",
                    np_=a.np_, timeout=6 * 3600)
    log = dem.check("in the DEM collapse", dem_out / "final_stress.dump")
    t_rest = float(re.search(END_RE, log, re.M).group(1))
    dt = logs.number(r"dt = ([-+.\deE]+) s \(tc/", log)
    ratios = deposit_stress(dem_out / "final_stress.dump", CELL_D * D)
    final = read_dump(dem_out / "final.dump")
    moving = final["type"] == 1
    dem_row = dict(rest_time_s=t_rest, cells=int(ratios.size), ratio_median=float(np.median(ratios)),
                   ratio_p90=float(np.percentile(ratios, 90)), share_above_mu_s=float(np.mean(ratios > mu_s)),
                   median_speed_mm_s=1e3 * float(np.median(np.hypot(final["vx"][moving], final["vy"][moving]))),
                   wall_s=dem.wall)
    print(f"DEM at rest at t = {t_rest:.3f} s: tau/p median {dem_row['ratio_median']:.3f}, p90 "
          f"{dem_row['ratio_p90']:.3f}, {dem_row['share_above_mu_s']:.0%} of {ratios.size} cells above mu_s {mu_s:.4f}",
          flush=True)

    hyb_out = a.work / "hybrid"
    hyb_out.mkdir(parents=True, exist_ok=True)
    frames_every = max(1, math.ceil(a.frame_every / (dt * EVERY)))    # houtev counts exchanges
    hyb = FORMS.run("hybrid", dict(common, out=str(hyb_out)), hyb_out / "log.lammps",
                    dict(hybrid=2, hcell=0, hevery=EVERY, hmaterial=MATERIAL, tmax=t_rest + a.after,
                         houtev=frames_every), np_=a.np_,
                    timeout=6 * 3600)
    hlog = hyb.check("in the hybrid collapse", hyb_out / "final.dump")
    kerest = float(re.search(END_RE, hlog, re.M).group(3))
    late = [r["v_kepg"] / kerest for r in logs.thermo_rows(hlog, require="v_kepg") if r["Time"] >= t_rest]
    run = load_run(hyb_out / "frames")
    indices = window_frames(run, t_rest)
    if len(indices) < 2:
        raise SystemExit(f"deposit_rest: the hybrid wrote {len(indices)} frame(s) after t = {t_rest:.3f} s; "
                         f"see {hyb_out / 'log.lammps'}")
    frames = points_state(run, indices, mu_s)
    grains = grains_state(run, indices)
    hyb_row = dict(
        frames=len(frames), window_s=[frames[0]["time"], frames[-1]["time"]],
        ke_over_rest_mean=float(np.mean(late)) if late else None, ke_over_rest_end=late[-1] if late else None,
        points_on_cone=float(np.mean([f["on_cone"] for f in frames])),
        points_ratio_median=float(np.mean([f["ratio_median"] for f in frames])),
        points_mean_v_mm_s=(1e3 * np.mean([f["mean_v"] for f in frames], axis=0)).tolist(),
        points_drift_mm_s=(1e3 * np.array(points_drift(frames[0], frames[-1]))).tolist(),
        hybrid_grains_mean_v_mm_s=(1e3 * np.mean([g["hybrid"]["mean_v"] for g in grains], axis=0)).tolist(),
        discrete_grains_mean_v_mm_s=(1e3 * np.mean([g["discrete"]["mean_v"] for g in grains], axis=0)).tolist(),
        hybrid_median_speed_mm_s=1e3 * float(np.mean([g["hybrid"]["median_speed"] for g in grains])),
        discrete_median_speed_mm_s=1e3 * float(np.mean([g["discrete"]["median_speed"] for g in grains])),
        wall_s=hyb.wall)
    print(f"hybrid after t = {t_rest:.3f} s ({len(frames)} frames): KE {hyb_row['ke_over_rest_mean']:.1f}x the rest "
          f"threshold, {hyb_row['points_on_cone']:.0%} of the points on the yield cone, points drift "
          f"{hyb_row['points_drift_mm_s']} mm/s, discrete grains {hyb_row['discrete_grains_mean_v_mm_s']} mm/s",
          flush=True)

    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    result = dict(date=stamp, width_d=a.width_d, aspect=ASPECT, np=a.np_, mu_s=mu_s, dem=dem_row, hybrid=hyb_row)
    a.out.with_suffix(".json").write_text(json.dumps(result, indent=1))
    command = "bench/deposit_rest.py " + " ".join(sys.argv[1:])
    v = lambda xy: f"({xy[0]:+.2f}, {xy[1]:+.2f})"    # noqa: E731
    write_report(a.out, "\n".join([
        "# Does the hybrid's deposit come to rest where the DEM's does?", "",
        f"`{command}`, {stamp}: the 2D column collapse, a = {ASPECT}, L0 = {a.width_d} d, pure LAMMPS DEM to rest "
        f"(t = {t_rest:.3f} s) and the adaptive hybrid (fix defaults, `hcell 0`) from the same column, run "
        f"{a.after} s longer; {a.np_} LAMMPS ranks. The continuum's friction mu_s = {mu_s:.4f} "
        f"(`{material_path(MATERIAL).relative_to(REPO)}`).", "",
        "| | DEM at rest | hybrid, after the DEM's rest time |", "| --- | --- | --- |",
        f"| stress ratio tau/p, median | {dem_row['ratio_median']:.3f} (cells of {CELL_D} d) | "
        f"{hyb_row['points_ratio_median']:.3f} (points) |",
        f"| share at or above mu_s | {dem_row['share_above_mu_s']:.0%} of {dem_row['cells']} cells (p90 "
        f"{dem_row['ratio_p90']:.3f}) | {hyb_row['points_on_cone']:.0%} of the points on the yield cone |",
        f"| kinetic energy per grain over the rest threshold | < 1 (at rest) | {hyb_row['ke_over_rest_mean']:.1f} "
        f"(mean), {hyb_row['ke_over_rest_end']:.1f} (end) |",
        f"| median grain speed, mm/s | {dem_row['median_speed_mm_s']:.3f} | hybrid grains "
        f"{hyb_row['hybrid_median_speed_mm_s']:.3f}, discrete {hyb_row['discrete_median_speed_mm_s']:.3f} |",
        f"| mean velocity (vx, vy), mm/s | | points {v(hyb_row['points_mean_v_mm_s'])}, drift "
        f"{v(hyb_row['points_drift_mm_s'])}; hybrid grains {v(hyb_row['hybrid_grains_mean_v_mm_s'])}; discrete "
        f"{v(hyb_row['discrete_grains_mean_v_mm_s'])} |",
        f"| wall time, s | {dem_row['wall_s']:.0f} | {hyb_row['wall_s']:.0f} |", ""]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
