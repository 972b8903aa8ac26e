#!/usr/bin/env python3
"""The 2D silo's flow field, pure LAMMPS DEM against its adaptive hybrid twin, side by side in one
invocation from the same cached packing (issue 14: where the hybrid's discharge differs).

The DEM and the hybrid (input_decks/silo/dem_2d.lmp + hybrid_2d.lmp, the decks' defaults, exchange
every 10, oracle every 100) discharge the 50 d silo of bench/adaptive_accuracy.py; the deck dumps the
grains every `tdump` (its variable), the hybrid's MPM process writes frames of its grains (with their
carried mass) and points (fix keyword `output`). Measures, over the window [t0, t1] after the opening:

- the mass below heights of 10, 20, 30 and 40 d over time, and its largest excess over the DEM's
  (the DEM's is steady within its grains' rattling: a compacting hybrid gains mass there);
- the mean descent velocity of each row of 2.5 d (mass-weighted; the DEM's bulk moves as a plug),
  and the velocity across the width at three heights;
- the hybrid cells' mixture: the points' and grains' mass per cell over a cell's mass at the packing
  (grains filling a hybrid cell at weight 0.5 leave room for half of it in points);
- where the mass sits: a map of the mass per area over the packing's, rows from the floor against the
  distance from the axis, DEM and hybrid.

Writes bench/results/silo_flow_field.json and .md (notes below the marker kept).

    bench/silo_flow_field.py [--np 2] [--seed 12345] [--t0 0.2] [--t1 0.8]
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from dem_silo import run_dem_silo  # noqa: E402
from hgtools.grains import read_dump  # noqa: E402
from hgtools.report import write_report  # noqa: E402
from mpm_results import load_run, read_grains  # noqa: E402

D = 0.002
SIZE = dict(width=0.1, height=0.15, orifice=0.02, tdis=1.0, fstop=0.9, d=D)   # bench/adaptive_accuracy.py's
ROW = 2.5 * D                 # rows and cells of the measures: the hybrid deck's cell
HEIGHTS_D = (10, 20, 30, 40)  # mass below these heights
PROFILE_D = (11.25, 21.25, 36.25)
TDUMP = 0.05                  # s between the DEM's grain dumps
FRAME_EXCHANGES = 150         # exchanges between the hybrid's frames (about 0.01 s at this deck's step)
FILL_ROW, FILL_TOP = 5 * D, 40 * D    # the fill map's rows, and its top (the orifice's discrete region and above)


def dem_timestep(out: Path) -> float:
    """The DEM time step of the silo deck's run in `out` (its 'DEM timestep' line), s."""
    return float(re.search(r"^DEM timestep: .*, dt = (\S+) s", (out / "log.lammps").read_text(), re.M).group(1))


def dem_states(out: Path) -> list[dict]:
    """Each grain dump of a run: t since the opening and the grains' y, x, vy and mass."""
    log = (out / "log.lammps").read_text()
    dt = dem_timestep(out)
    opened = int(re.search(r"^DEM silo open: .*, step (\d+),", log, re.M).group(1))
    states = []
    for f in out.glob("flow.*.dump"):
        g = read_dump(f)
        states.append(dict(t=(int(f.name.split(".")[1]) - opened) * dt, x=g["x"], y=g["y"], vy=g["vy"], m=g["mass"]))
    return sorted(states, key=lambda s: s["t"])


def hybrid_states(out: Path) -> tuple[list[dict], np.ndarray]:
    """The same from the hybrid's MPM frames, grains (their carried mass) and points together, with
    each body's zone and whether it is a point; and the grid's origin (the cells' lower corner)."""
    run = load_run(out / "frames")
    states = []
    for info in run.frames:
        pts = run.frame(info.index, fields=("position", "velocity", "mass", "zone"))
        g = read_grains(run.path, info.index)
        # grains' vectors have three components also in 2D, the points' two: take the columns
        both = lambda key, col=None: np.concatenate(  # noqa: E731
            [g[key] if col is None else g[key][:, col], pts[key] if col is None else pts[key][:, col]])
        states.append(dict(t=info.time, x=both("position", 0), y=both("position", 1), vy=both("velocity", 1),
                           m=both("mass"), zone=both("zone"),
                           point=np.arange(len(g["mass"]) + len(pts["mass"])) >= len(g["mass"])))
    return states, run.grid["origin"]


def in_window(states, t0: float, t1: float) -> list[dict]:
    return [s for s in states if t0 <= s["t"] <= t1]


def mass_below(states, heights_d=HEIGHTS_D) -> dict:
    """Each state's time and its mass above the floor and below each height (in grain diameters)."""
    return dict(t=[s["t"] for s in states],
                mass=[[float(s["m"][(s["y"] > 0) & (s["y"] < h * D)].sum()) for h in heights_d] for s in states])


def profiles(states, width: float) -> dict:
    """Mass-weighted vy per row (the row's mean) and per column at PROFILE_D, averaged over the states."""
    nx, ny = int(round(width / ROW)), int(np.ceil(SIZE["height"] / ROW))
    m_sum, p_sum = np.zeros((ny, nx)), np.zeros((ny, nx))
    for s in states:
        ix, iy = np.clip((s["x"] / ROW).astype(int), 0, nx - 1), (s["y"] / ROW).astype(int)
        ok = (iy >= 0) & (iy < ny)
        np.add.at(m_sum, (iy[ok], ix[ok]), s["m"][ok])
        np.add.at(p_sum, (iy[ok], ix[ok]), (s["m"] * s["vy"])[ok])
    row_v = p_sum.sum(axis=1) / np.maximum(m_sum.sum(axis=1), 1e-30)
    cols = {f"{h:g}": (p_sum[int(h * D / ROW)] / np.maximum(m_sum[int(h * D / ROW)], 1e-30)).tolist() for h in PROFILE_D}
    return dict(row_height_d=[(j + 0.5) * ROW / D for j in range(ny)], row_vy=row_v.tolist(), columns_vy=cols)


def hybrid_cells(states, origin: np.ndarray, packed_cell_mass: float) -> dict:
    """Per band of 10 d: the hybrid cells' (the MPM grid's cells, from `origin`, that hold hybrid points)
    points' and grains' mass per cell over a cell's at the packing."""
    bands = range(0, 70, 10)
    pts, grs, n = dict.fromkeys(bands, 0.0), dict.fromkeys(bands, 0.0), dict.fromkeys(bands, 0)
    for s in states:
        ix, iy = (np.floor((s[c] - origin[k]) / ROW).astype(int) for k, c in enumerate("xy"))
        cell = ix * 100000 + iy
        hybrid_point = s["point"] & (s["zone"] == 1)
        for lo in bands:    # the cells holding a hybrid point in the band
            mine = np.unique(cell[hybrid_point & (s["y"] >= lo * D) & (s["y"] < (lo + 10) * D)])
            sel = np.isin(cell, mine)
            pts[lo] += s["m"][sel & s["point"]].sum()
            grs[lo] += s["m"][sel & ~s["point"]].sum()
            n[lo] += len(mine)
    return {f"{lo}-{lo + 10}": dict(points=pts[lo] / n[lo] / packed_cell_mass, grains=grs[lo] / n[lo] / packed_cell_mass,
                                    cells=n[lo]) for lo in bands if n[lo]}


def fill_map(states, packed_density: float) -> list[list[float]]:
    """Mass per area over the packing's (grains' carried mass and points together), averaged over the
    states: rows of FILL_ROW from the floor up to FILL_TOP, columns of ROW by the distance from the
    silo's axis (the two sides together: the silo is symmetric)."""
    rows, cols = np.arange(0, FILL_TOP + 1e-12, FILL_ROW), np.arange(0, SIZE["width"] / 2 + 1e-12, ROW)
    acc = np.zeros((len(rows) - 1, len(cols) - 1))
    for s in states:
        acc += np.histogram2d(s["y"], np.abs(s["x"] - SIZE["width"] / 2), bins=(rows, cols), weights=s["m"])[0]
    return (acc / max(len(states), 1) / (2 * FILL_ROW * ROW) / packed_density).tolist()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--np", type=int, default=2, dest="np_")
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--t0", type=float, default=0.2)
    ap.add_argument("--t1", type=float, default=0.8)
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "silo_flow_field.md")
    a = ap.parse_args()
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    common = dict(np_=a.np_, seed=a.seed, **SIZE)
    contact = {"mu": 0.5, "e": 0.5}
    with tempfile.TemporaryDirectory(prefix="silo_flow_field_") as tmp:
        work = Path(tmp)
        dem = run_dem_silo(out=work / "dem", extra_vars={**contact, "tdump": TDUMP}, **common)
        hyb = run_dem_silo(out=work / "hybrid", extra_vars=contact,
                           hybrid_vars={"hevery": 10, "hadapt": 100, "houtev": FRAME_EXCHANGES}, **common)
        ds, (hs, origin) = dem_states(work / "dem"), hybrid_states(work / "hybrid")
    packed_density = dem.packing * 2500.0        # the settled packing's mass per area (2D: kg/m per m^2)
    packed = packed_density * ROW * ROW          # a cell's mass at it (kg/m)
    fills = {name: fill_map(in_window(states, a.t0, a.t1), packed_density) for name, states in (("dem", ds), ("hybrid", hs))}
    res = dict(date=stamp, seed=a.seed, window_s=[a.t0, a.t1], grains=dem.grains, heights_d=list(HEIGHTS_D),
               rate_dem=dem.rate, rate_hybrid=hyb.rate, rate_error=hyb.rate / dem.rate - 1,
               dem=dict(mass_below=mass_below(in_window(ds, 0.0, a.t1 + 0.2)),
                        **profiles(in_window(ds, a.t0, a.t1), SIZE["width"])),
               hybrid=dict(mass_below=mass_below(in_window(hs, 0.0, a.t1 + 0.2)),
                           **profiles(in_window(hs, a.t0, a.t1), SIZE["width"]),
                           hybrid_cells=hybrid_cells(in_window(hs, a.t0, a.t1), origin, packed)))
    # the largest excess of the hybrid's mass below each height over the DEM's at the same time
    dm, hm = res["dem"]["mass_below"], res["hybrid"]["mass_below"]
    excess = []
    for k in range(len(HEIGHTS_D)):
        d_at = np.interp(hm["t"], dm["t"], [m[k] for m in dm["mass"]])
        excess.append(float(np.max(np.array([m[k] for m in hm["mass"]]) / d_at - 1)))
    res["mass_below_excess"] = excess
    res["fill_map"] = dict(row_d=FILL_ROW / D, column_d=ROW / D, **fills)
    a.out.with_suffix(".json").write_text(json.dumps(res, indent=1))
    lines = ["# The 2D silo's flow field: LAMMPS DEM against the adaptive hybrid", "",
             f"`bench/silo_flow_field.py --np {a.np_} --seed {a.seed} --t0 {a.t0:g} --t1 {a.t1:g}`, {stamp}: the 50 d "
             f"silo ({dem.grains} disks, D = 10 d), both from the same packing; the hybrid at the decks' defaults "
             f"(every 10, oracle 100). Rates: DEM {dem.rate:.3f}, hybrid {hyb.rate:.3f} kg/s/m "
             f"({100 * res['rate_error']:+.1f} %).", "",
             "| height (d) | mass below, DEM, kg/m (first / last) | hybrid (first / last) | largest hybrid excess |",
             "| --- | --- | --- | --- |"]
    for k, h in enumerate(HEIGHTS_D):
        lines.append(f"| {h} | {dm['mass'][0][k]:.2f} / {dm['mass'][-1][k]:.2f} | {hm['mass'][0][k]:.2f} / "
                     f"{hm['mass'][-1][k]:.2f} | {100 * excess[k]:+.1f} % |")
    lines += ["", f"Mean descent velocity of the rows (mm/s, mass-weighted, {a.t0:g}-{a.t1:g} s):", "",
              "| height (d) | DEM | hybrid |", "| --- | --- | --- |"]
    for j, h in enumerate(res["dem"]["row_height_d"]):
        if j % 2 == 0 and h < 60:
            lines.append(f"| {h:.2f} | {1000 * res['dem']['row_vy'][j]:.1f} | {1000 * res['hybrid']['row_vy'][j]:.1f} |")
    lines += ["", "Across the width (mm/s, columns of 2.5 d from the left wall):", ""]
    for h in PROFILE_D:
        for name in ("dem", "hybrid"):
            lines.append(f"- {h:g} d, {name}: " + " ".join(f"{1000 * v:.0f}" for v in res[name]["columns_vy"][f"{h:g}"]))
    lines += ["", "The hybrid cells' mixture, per cell over a cell's mass at the settled packing "
              f"({packed:.4f} kg/m):", "", "| band (d) | points | grains | together | cell-frames |", "| --- | --- | --- | --- | --- |"]
    for band, c in res["hybrid"]["hybrid_cells"].items():
        lines.append(f"| {band} | {c['points']:.2f} | {c['grains']:.2f} | {c['points'] + c['grains']:.2f} | {c['cells']} |")
    lines += ["", f"Where the mass sits ({a.t0:g}-{a.t1:g} s): mass per area over the packing's, rows of "
              f"{FILL_ROW / D:g} d from the floor, columns of {ROW / D:g} d by the distance from the axis (the orifice's "
              f"half-width is {SIZE['orifice'] / 2 / D:g} d, its discrete region {2 * SIZE['orifice'] / D:g} d high):", "",
              "| rows (d) | run | " + " | ".join(f"{k * ROW / D:g}-{(k + 1) * ROW / D:g}" for k in range(len(fills["dem"][0])))
              + " |", "| --- | --- |" + " --- |" * len(fills["dem"][0])]
    for i in range(len(fills["dem"])):
        for name in ("dem", "hybrid"):
            lines.append(f"| {i * FILL_ROW / D:g}-{(i + 1) * FILL_ROW / D:g} | {name} | "
                         + " | ".join(f"{v:.2f}" for v in fills[name][i]) + " |")
    write_report(a.out, "\n".join(lines))
    print(f"wrote {a.out}: rate {100 * res['rate_error']:+.1f} %, mass below 30 d up to {100 * excess[2]:+.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
