#!/usr/bin/env python3
"""A bed at rest must stay at rest (issue 14): the settled 2D column of the collapse, its right
wall kept, as pure LAMMPS DEM and as the adaptive hybrid, side by side from the same cached
settled column.

Scene: input_decks/column_collapse/dem_2d.lmp with `gate 1` (the column is not released and runs
`tbed` seconds), a = 2, L0 = n d. The hybrid is its `hybrid 2` twin with the fix's grid from the
grains (`hcell 0`) and the fix's defaults, then once per agreement relaxation time given with
--relax (fix keyword relax; 0 = the gap closed whole at every exchange).

Measures per run, over the second half of the run: the mean kinetic energy per grain (the deck's
rest criterion: below 1e-5 m g d it is at rest), and at the end the creep: the mean vertical
velocity of the grains in the bed's top 4 d (a bed at rest does not move; a bed that compacts
sinks fastest at its top).

Usage: bench/settled_bed.py [--np 2] [--width-d 50] [--tbed 0.2] [--relax 0,8e-4]
Writes bench/results/settled_bed.json and settled_bed.md (notes below the marker kept).
"""
from __future__ import annotations

import argparse
import json
import sys
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from dem_collapse import run_bed  # noqa: E402
from hgtools.report import write_report  # noqa: E402

D = 0.002        # grain diameter, m (the deck's)


def table(rows: list[dict]) -> list[str]:
    lines = ["| run | grains at the end | KE per grain (late half) | over the rest threshold | top 4 d, mean vy | wall s |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        lines.append(f"| {r['label']} | {r['grains']} | {r['ke_per_grain']:.2e} J | {r['ke_over_rest']:.2f} | "
                     f"{r['top_vy_mm_s']:+.3f} mm/s | {r['wall_s']:.0f} |")
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--np", type=int, default=2, dest="np_", help="LAMMPS ranks, DEM and hybrid alike")
    ap.add_argument("--width-d", type=int, default=50, help="L0 in grain diameters")
    ap.add_argument("--tbed", type=float, default=0.2, help="time the bed runs, s")
    ap.add_argument("--relax", default="0,8e-4", help="extra hybrid runs at these agreement relaxation times, s ('' = none)")
    ap.add_argument("--work", type=Path, default=REPO / "runs" / "settled_bed")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "settled_bed.md")
    a = ap.parse_args()
    width = a.width_d * D
    runs = [("LAMMPS DEM", None), ("hybrid, fix defaults", {"hybrid": 2, "hcell": 0})]
    runs += [(f"hybrid, relax {t} s", {"hybrid": 2, "hcell": 0, "hrelax": t}) for t in a.relax.split(",") if t]
    rows = []
    for label, hybrid_vars in runs:
        out = a.work / label.replace(" ", "_").replace(",", "")
        bed = run_bed(aspect=2.0, width=width, d=D, np_=a.np_, out=out, tbed=a.tbed, hybrid_vars=hybrid_vars)
        r = dict(label=label, width_d=a.width_d, tbed_s=a.tbed, np=a.np_, grains=bed.grains,
                 ke_per_grain=bed.ke_per_grain, ke_over_rest=bed.ke_per_grain / bed.ke_rest,
                 top_vy_mm_s=1e3 * bed.top_vy, wall_s=bed.wall_time)
        rows.append(r)
        print(f"{label}: KE/grain {r['ke_per_grain']:.2e} J ({r['ke_over_rest']:.2f}x rest), "
              f"top vy {r['top_vy_mm_s']:+.3f} mm/s, {r['wall_s']:.0f} s", flush=True)
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    a.out.with_suffix(".json").write_text(json.dumps(dict(date=stamp, rows=rows), indent=1))
    command = "bench/settled_bed.py " + " ".join(sys.argv[1:])
    write_report(a.out, "\n".join([
        "# A settled bed must stay at rest", "",
        f"`{command}`, {stamp}: the 2D column (a = 2, L0 = {a.width_d} d) kept behind its gate for "
        f"{a.tbed} s, pure DEM and hybrid from the same settled column on {a.np_} LAMMPS ranks.", "",
        *table(rows), ""]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
