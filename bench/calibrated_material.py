#!/usr/bin/env python3
"""The adaptive hybrid with the continuum calibrated from the grains (input_decks/materials,
tools/calibrate.py) against the same hybrid with the constants the decks used to guess
(Drucker-Prager 30 degrees, E = kn) and against pure LAMMPS DEM, side by side in one run from the
same settled states (issue 14: "no scene picks these numbers by hand").

Scenes: the 2D column collapse, a = 2, at L0 = 25 d and 50 d (runout, final surface of the grains'
connected deposit over H0, steps to rest over the DEM's); the 2D silo, W = 50 d, D = 10 d
(steady discharge rate). Every hybrid runs with the fix's and the decks' defaults otherwise
(adaptive zones, exchange every 10, oracle every 100).

Each scene runs from every packing of --seeds (the DEM of each packing is that packing's
reference; the DEMs of the other packings against the first give the DEM's own noise floor).

Usage: bench/calibrated_material.py [--np 2] [--scenes collapse_25d,collapse_50d,silo] [--seeds 12345,2]
Writes bench/results/calibrated_material.json (a list `rows`) and .md.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from column_collapse import surface_error  # noqa: E402
from dem_collapse import run as run_collapse, run_from_settled  # noqa: E402
from calibrate import describe_material  # noqa: E402
from dem_silo import run_dem_silo  # noqa: E402

D = 0.002
CONTINUA = {"calibrated": {}, "guessed": {"hmaterial": "none"}}   # the decks' defaults: disks_2d / 30 deg, E = kn
RESULTS = REPO / "bench" / "results"


def collapse(work: Path, np_: int, width: float, seed: int) -> list[dict]:
    dem = run_from_settled(aspect=2.0, width=width, d=D, np_=np_, out=work / "dem", seed=seed, timeout=7200)
    reference = np.array(dem.profile).T
    rows = [dict(scene="collapse_2d", size_d=round(width / D), seed=seed, grains=dem.grains, continuum="none (DEM)",
                 runout=dem.runout, wall_s=dem.wall_time, steps=dem.steps, profile=dem.profile, height=dem.height)]
    for name, hvars in CONTINUA.items():
        h = run_collapse(2.0, width, D, np_=np_, out=work / name, seed=seed, hybrid_vars={"hybrid": 2, **hvars},
                         timeout=7200)
        rows.append(dict(scene="collapse_2d", size_d=round(width / D), seed=seed, grains=dem.grains, continuum=name,
                         runout=h.runout, runout_error=h.runout / dem.runout - 1,
                         surface_error=surface_error(np.array(h.profile).T, reference, dem.height),
                         steps=h.steps, steps_ratio=h.steps / dem.steps, at_rest=h.at_rest,
                         wall_s=h.wall_time, speed_vs_dem=dem.wall_time / h.wall_time))
        print(rows[-1], flush=True)
    return rows


def silo(work: Path, np_: int, seed: int) -> list[dict]:
    common = dict(np_=np_, tdis=0.6, timeout=7200, seed=seed)
    dem = run_dem_silo(out=work / "dem", **common)
    rows = [dict(scene="silo_2d", size_d=round(0.1 / D), seed=seed, grains=dem.grains, continuum="none (DEM)",
                 rate=dem.rate, wall_s=dem.wall_time)]
    for name, hvars in CONTINUA.items():
        h = run_dem_silo(out=work / name, hybrid_vars=dict(hvars), **common)
        rows.append(dict(scene="silo_2d", size_d=round(0.1 / D), seed=seed, grains=dem.grains, continuum=name,
                         rate=h.rate,
                         rate_error=h.rate / dem.rate - 1, wall_s=h.wall_time, speed_vs_dem=dem.wall_time / h.wall_time))
        print(rows[-1], flush=True)
    return rows


def noise_floor(rows: list[dict]) -> list[dict]:
    """The DEM of every other packing against the first packing's DEM, per scene and size."""
    floors = []
    for key in dict.fromkeys((r["scene"], r["size_d"]) for r in rows):
        dems = [r for r in rows if (r["scene"], r["size_d"]) == key and r["continuum"] == "none (DEM)"]
        for other in dems[1:]:
            ref = dems[0]
            row = dict(scene=key[0], size_d=key[1], seed=other["seed"], grains=other["grains"],
                       continuum=f"DEM of packing {other['seed']} against packing {ref['seed']} (noise floor)")
            if "runout" in ref:
                row.update(runout=other["runout"], runout_error=other["runout"] / ref["runout"] - 1,
                           surface_error=surface_error(np.array(other["profile"]).T, np.array(ref["profile"]).T,
                                                       ref["height"]),
                           steps_ratio=other["steps"] / ref["steps"])
            else:
                row.update(rate=other["rate"], rate_error=other["rate"] / ref["rate"] - 1)
            floors.append(row)
    return floors


def table(rows: list[dict]) -> str:
    out = ["| scene | size | packing | grains | continuum | runout or rate | error against DEM | final surface / H0 | "
           "steps to rest / DEM's | speed vs DEM |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        measure = f"{r['runout']:.3f}" if "runout" in r else f"{r['rate']:.3f} kg/s/m"
        err = r.get("runout_error", r.get("rate_error"))
        out.append(f"| {r['scene']} | {r['size_d']} d | {r['seed']} | {r['grains']} | {r['continuum']} | {measure} | "
                   f"{'' if err is None else f'{err:+.1%}'} | "
                   f"{'' if 'surface_error' not in r else format(r['surface_error'], '.1%')} | "
                   f"{'' if 'steps_ratio' not in r else format(r['steps_ratio'], '.2f')} | "
                   f"{'' if 'speed_vs_dem' not in r else format(r['speed_vs_dem'], '.2f') + 'x'} |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--np", type=int, default=2, dest="np_", help="LAMMPS ranks of every run")
    ap.add_argument("--scenes", default="collapse_25d,collapse_50d,silo")
    ap.add_argument("--seeds", default="12345,2", help="packings (seeds of the settled states)")
    ap.add_argument("--work", default=None, help="directory of the runs (default: a temporary one)")
    a = ap.parse_args(argv)
    scenes = a.scenes.split(",")
    unknown = set(scenes) - {"collapse_25d", "collapse_50d", "silo"}
    if unknown:
        ap.error(f"unknown scenes {sorted(unknown)}")
    work = Path(a.work or tempfile.mkdtemp(prefix="calibrated_material_")).resolve()
    try:
        seeds = [int(s) for s in a.seeds.split(",")]
    except ValueError:
        ap.error(f"--seeds takes integers separated by commas, not {a.seeds!r}")
    rows = []
    for s in scenes:
        for seed in seeds:
            if s.startswith("collapse"):
                size = int(s.split("_")[1][:-1])
                rows += collapse(work / s / f"seed{seed}", a.np_, size * D, seed)
            else:
                rows += silo(work / s / f"seed{seed}", a.np_, seed)
    rows += noise_floor(rows)
    for r in rows:
        r.pop("profile", None)
    RESULTS.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    (RESULTS / "calibrated_material.json").write_text(json.dumps({"date": stamp, "np": a.np_, "rows": rows}, indent=1))
    (RESULTS / "calibrated_material.md").write_text(
        f"# The continuum calibrated from the grains against the decks' guessed constants\n\n"
        f"`bench/calibrated_material.py --np {a.np_} --scenes {a.scenes} --seeds {a.seeds}`, {stamp}; {a.np_} LAMMPS rank(s) for DEM and "
        f"hybrid alike (plus one MPM process for the hybrid) on a 2-core machine, side by side in one run from the same "
        f"settled states. calibrated: {describe_material('disks_2d')}; guessed: `youngs kn friction 30` (the decks "
        f"before the calibration). Adaptive zones, "
        f"exchange every 10, oracle every 100. The final surface is that of the grains' connected deposit. "
        f"Each hybrid is compared with the DEM of its own packing; the last rows are the DEM's own noise floor.\n\n"
        + table(rows) + "\n")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
