#!/usr/bin/env python3
"""Where a coupled run's time goes, both sides, read from a run alone (issue 15).

Interleaved (bench/scale_speed.py), a run's time ledgers count the quanta in which it was stopped
(docs/design.md 7.3), so the split of a hybrid's time is measured here on its own: the 2D column
collapse, a = 2, L0 = n d (input_decks/column_collapse/dem_2d.lmp, `hybrid 2`, `hcell 0`; with
--touch 1 the continuum may touch the back wall and the floor), from the cached settled column to
rest, alone on the machine.

Measures, summed over the deck's runs: LAMMPS's own timing breakdown (Pair, Neigh, Comm, Modify,
Other), the fix's (Exchange, MPM wait, Apply, Rezone, Oracle, Output, Coupling), the MPM process's
ledger (`docs/fix_hybrid_mpm.md` "Timing breakdown": waiting for the DEM host, substeps, agreement,
replies and acknowledgement, G2P, rezones, ...), the steps, exchanges and runout; per exchange,
the time the continuum holds the DEM host (substeps before the agreement, agreement, replies).
--build runs another build of the project (e.g. one configured with -DHYBRID_NATIVE=OFF), as
HYBRID_BUILD_DIR; --label names the row (rows of other labels are kept).

Usage: bench/coupling_ledger.py [--width-d 100] [--touch 1] [--np 2] [--threads 2] [--build DIR] [--label native]
Writes bench/results/coupling_ledger.json and coupling_ledger.md (notes below the marker kept).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from dem_collapse import run as run_collapse  # noqa: E402
from hgtools.logs import mpm_ledger, timing_sections  # noqa: E402
from hgtools.report import write_report  # noqa: E402

RESULTS = REPO / "bench" / "results"
D = 0.002          # grain diameter, m (bench/scale_speed.py's)
ASPECT = 2.0
CRITICAL_PATH = ("substeps before the agreement", "agreement", "replies and acknowledgement")


def measure(n: int, touch: int, np_: int, threads: int, build: Path | None, work: Path) -> dict:
    hybrid_vars = {"hybrid": 2, "hcell": "0"} | ({"htouch": 1} if touch else {})
    if build is not None:
        os.environ["HYBRID_BUILD_DIR"] = str(build)
    os.environ["OMP_NUM_THREADS"] = str(threads)
    t0 = time.monotonic()
    r = run_collapse(out=work, aspect=ASPECT, width=n * D, d=D, np_=np_, seed=12345, timeout=4 * 3600,
                     hybrid_vars=hybrid_vars)
    wall = time.monotonic() - t0
    log = (work / "log.lammps").read_text()
    mpm = mpm_ledger((work / "log.lammps.out").read_text())
    exchanges = int(re.findall(r"coupled run finished at .* after (\d+) exchange", (work / "log.lammps.out").read_text())[-1])
    return dict(width_d=n, touch=touch, lammps_ranks=np_, mpm_threads=threads, build=str(build or REPO / "build"),
                steps=r.steps, runout=r.runout, wall_s=wall, loop_s=r.loop_time, exchanges=exchanges,
                lammps=timing_sections(log, "MPI task timing breakdown"),
                fix=timing_sections(log, "fix hybrid/mpm timing breakdown"), mpm=mpm,
                held_per_exchange_us=1e6 * sum(mpm[k] for k in CRITICAL_PATH) / max(exchanges, 1))


def table(rows: dict[str, dict]) -> list[str]:
    out = ["| label | L0 (d), touch | steps | runout | loop s | coupling s (share) | fix: MPM wait, oracle, rezone, "
           "exchange, apply s | LAMMPS: Pair, Modify s | MPM: waiting, agreement, replies, G2P, rezones s | "
           "held per exchange | measured (UTC) |",
           "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for label, r in rows.items():
        f, lmp, m = r["fix"], r["lammps"], r["mpm"]
        out.append(
            f"| {label} | {r['width_d']}, {r['touch']} | {r['steps']} | {r['runout']:.4f} | {r['loop_s']:.1f} | "
            f"{f['Coupling']:.1f} ({f['Coupling'] / r['loop_s']:.0%}) | {f['MPM wait']:.1f}, {f['Oracle']:.1f}, "
            f"{f['Rezone']:.1f}, {f['Exchange']:.1f}, {f['Apply']:.1f} | {lmp['Pair']:.1f}, {lmp['Modify']:.1f} | "
            f"{m['waiting for the DEM host']:.0f}, {m['agreement']:.2f}, {m['replies and acknowledgement']:.2f}, "
            f"{m['G2P']:.2f}, {m['rezones']:.2f} | {r['held_per_exchange_us']:.0f} us | {r['date']} |")
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width-d", type=int, default=100, help="column width L0 in grain diameters")
    ap.add_argument("--touch", type=int, choices=(0, 1), default=1, help="1: the continuum touches the back wall and floor")
    ap.add_argument("--np", type=int, default=2, dest="np_", help="LAMMPS ranks")
    ap.add_argument("--threads", type=int, default=2, help="the MPM process's OpenMP threads")
    ap.add_argument("--build", type=Path, default=None, help="another build directory of this project")
    ap.add_argument("--label", default="native", help="the row's name in the results")
    ap.add_argument("--work", type=Path, default=REPO / "runs" / "coupling_ledger")
    a = ap.parse_args()
    if a.build is not None and not (a.build / "mpm_solver" / "mpm_solver").exists():
        ap.error(f"--build {a.build} holds no mpm_solver/mpm_solver: build it first (cmake --build {a.build})")
    path = RESULTS / "coupling_ledger.json"
    rows = json.loads(path.read_text())["rows"] if path.exists() else {}
    row = measure(a.width_d, a.touch, a.np_, a.threads, a.build, a.work / a.label)
    row["date"] = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M")
    rows[a.label] = row
    path.write_text(json.dumps(dict(rows=rows), indent=1))
    write_report(RESULTS / "coupling_ledger.md", "\n".join(
        ["# Where a coupled run's time goes, alone", "",
         "`bench/coupling_ledger.py`: the 2D collapse's adaptive hybrid alone, both sides' time ledgers summed over "
         "the deck's runs; 'held per exchange' is the MPM's substeps before the agreement, the agreement and its "
         "replies over the exchanges: what an exchange makes the DEM host wait.", "", *table(rows), ""]))
    print(f"{a.label}: loop {row['loop_s']:.1f} s, coupling {row['fix']['Coupling']:.1f} s, {row['steps']} steps, "
          f"runout {row['runout']:.4f}, held {row['held_per_exchange_us']:.0f} us per exchange", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
