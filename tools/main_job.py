#!/usr/bin/env python3
"""The main job: the default scene, a planar granular column collapse (aspect
ratio 2, L0 = 0.1 m), with its comparison output.

The collapse runs as pure LAMMPS DEM (the reference, input_decks/column_collapse/
dem_2d.lmp), as the hybrid (the same deck with `hybrid 1`: lmp_hybrid + mpm_solver,
fix hybrid/mpm, from the same settled column) and as pure MPM with each constitutive
model; each is compared with the DEM (final surface, runout, wall time) and with the
published runout laws (docs/design.md section 6), by tools/collapse_report.py (which also
runs the wider matrix: adaptive zones, the reference's noise floors).

Writes <out>/report.md (table), <out>/profiles.png (final surface profiles) and
<out>/error_vs_time.png.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from collapse_report import SOLVER, run_report

REPO = Path(__file__).resolve().parent.parent
RUNS = ["dem", "hybrid_fixed", "mpm_drucker_prager", "mpm_mu_i"]


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
    run_report(args.out, RUNS, args.aspect, 0.1, args.cell, args.threads, command="tools/main_job.py")
    print((args.out / "report.md").read_text())
    print(f"main_job: report {args.out / 'report.md'}, plots {args.out / 'profiles.png'}, "
          f"{args.out / 'error_vs_time.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
