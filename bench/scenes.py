#!/usr/bin/env python3
"""Wall time and error of the hybrid against pure LAMMPS DEM (and LIGGGHTS) on the 3D scenes of
issue 5, each at the reduced size its test uses, side by side in one invocation:

- 3D column collapse, a = 2, L0 = 15 d, slab 6 d thick between side walls, ~2,760 spheres
  (tools/dem3d_collapse.py; hybrid: a fixed continuum block, hybrid_3d.lmp): runout;
- 3D silo, W = 15 d, H = 20 d, circular orifice D = 6 d, ~4,700 spheres (tools/dem3d_silo.py;
  hybrid: adaptive zones): steady discharge rate;
- plough, blade 4 d deep dragged 3 h at 0.1 m/s through a bed 12 d deep in a slab 10.8 d thick
  between frictionless side walls, ~4,700 spheres (tools/dem_plough.py; hybrid: adaptive zones
  with a discrete region moving with the blade): mean drag;
- impact, a 6 d sphere shot at 4 m/s into a bed 12 d deep in a 14.4 d box, ~2,500 spheres
  (tools/dem_impact.py; hybrid: adaptive zones, a discrete cylinder under the impact):
  penetration depth.

Each form runs from the same initial grains (or settled bed) as the LAMMPS reference. Wall
times are those of the scene's own stage as its driver measures them (collapse: the loop times
after the gate opens; silo: the discharge; impact: the impact stage; plough: the whole run,
pour and settling included, for every form). Ratios are the DEM's wall time over each run's in
this job (the machine is shared: compare ratios, not absolute times).

Usage: bench/scenes.py [--np 2] [--only collapse3d,silo3d,plough,impact]
Writes bench/results/scenes.md and .json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

from tqdm import tqdm

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
RESULTS = REPO / "bench" / "results"
SEED = 2024


def collapse3d(np_: int, work: Path) -> dict:
    from dem3d_collapse import run
    runs = {code: run(code, np_=np_, seed=SEED, thickness_d=5, extra_vars={"walls": 1},
                      out=work / f"collapse_{code}", timeout=3600) for code in ("lammps", "liggghts", "hybrid")}
    return {code: dict(measure=r.runout, wall=r.collapse_wall) for code, r in runs.items()}


def silo3d(np_: int, work: Path) -> dict:
    from dem3d_silo import run
    common = dict(width=0.03, height=0.04, orifice=0.012, d=0.002, np_=np_, seed=SEED, prep_code="lammps",
                  cache_dir=work / "silo_cache", tdis=1.0, fstop=0.5, timeout=3600)
    runs = {code: run(code, out=work / f"silo_{code}", **common) for code in ("lammps", "liggghts", "hybrid")}
    return {code: dict(measure=r.rate, wall=r.wall_time) for code, r in runs.items()}


def plough(np_: int, work: Path) -> dict:
    from dem_plough import run
    thick = dict(bedh=0.024, thickness_d=9)
    runs = {code: run(code, 0.008, d=0.002, np_=np_, seed=SEED, out=work / f"plough_{code}", timeout=3600,
                      extra_vars={"zwall": 1} if code != "hybrid" else None, **thick)
            for code in ("lammps", "liggghts", "hybrid")}
    return {code: dict(measure=r.drag, wall=r.wall_time) for code, r in runs.items()}


def impact(np_: int, work: Path) -> dict:
    from dem_impact import run
    common = dict(width_rows=12, depth=0.024, d=0.002, dp=0.012, speed=4.0, rhop=2500.0, seed=SEED, timeout=3600)
    runs = {"lammps": run("lammps", out=work / "impact_lammps", np_=np_, **common)}
    bed = runs["lammps"].bed
    runs["liggghts"] = run("liggghts", out=work / "impact_liggghts", np_=np_, bed=bed, **common)
    # the hybrid: one LAMMPS rank plus the MPM process on the 2 cores (as its test)
    runs["hybrid"] = run("hybrid", out=work / "impact_hybrid", np_=max(1, np_ - 1), bed=bed,
                         hybrid_vars=dict(hcell=0.004, hdepth=0.0044, hband=0.0036, hradius=0.012), **common)
    return {code: dict(measure=r.penetration, wall=r.wall_time) for code, r in runs.items()}


SCENES = {
    "collapse3d": ("3D column collapse (a = 2, slab between side walls)", "runout (Lf - L0)/L0", collapse3d),
    "silo3d": ("3D silo discharge", "discharge rate, kg/s", silo3d),
    "plough": ("plough (blade dragged through a bed)", "mean drag, N", plough),
    "impact": ("high-speed impact (4 m/s)", "penetration depth, m", impact),
}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--np", dest="np_", type=int, default=2)
    p.add_argument("--only", default=",".join(SCENES))
    args = p.parse_args(argv)
    os.environ.setdefault("HYBRID_BUILD_DIR", str(REPO / "build"))
    os.environ["OMP_NUM_THREADS"] = "1"
    names = [n.strip() for n in args.only.split(",") if n.strip()]
    results = {}
    with tempfile.TemporaryDirectory(prefix="bench_scenes_") as tmp:
        for name in tqdm(names, desc="scenes", unit="scene"):
            results[name] = SCENES[name][2](args.np_, Path(tmp))
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"# Hybrid against pure DEM on the 3D scenes (bench/scenes.py, {stamp}, {args.np_} ranks)", "",
             "Reduced sizes (those of the tests); each form from the same initial grains; speedup = the LAMMPS "
             "run's wall time over the run's, in this job.", "",
             "| scene | measure | LAMMPS | LIGGGHTS (vs LAMMPS) | hybrid (vs LAMMPS) | LIGGGHTS speed vs LAMMPS | "
             "hybrid speedup vs LAMMPS |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, r in results.items():
        label, measure, _ = SCENES[name]
        ref = r["lammps"]
        for code in ("liggghts", "hybrid"):
            r[code]["error"] = r[code]["measure"] / ref["measure"] - 1
            r[code]["speedup"] = ref["wall"] / r[code]["wall"]
        lines.append(f"| {label} | {measure} | {ref['measure']:.4g} ({ref['wall']:.0f} s) | "
                     f"{r['liggghts']['measure']:.4g} ({r['liggghts']['error']:+.1%}) | "
                     f"{r['hybrid']['measure']:.4g} ({r['hybrid']['error']:+.1%}) | {r['liggghts']['speedup']:.2f}x | "
                     f"{r['hybrid']['speedup']:.2f}x |")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "scenes.md").write_text("\n".join(lines) + "\n")
    (RESULTS / "scenes.json").write_text(json.dumps(dict(date=stamp, np=args.np_, scenes=results), indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
