#!/usr/bin/env python3
"""MPM throughput and memory: material-point-steps per second per core in 2D
and 3D (Drucker-Prager), with 1 and 2 threads, and memory per material point.

Each case is a sand block collapsing in a box (the points move, yield and
touch walls, so every branch of the step is exercised). Rates come from
mpm_solver's own --summary figures for a fixed number of steps; memory per
point is the slope of peak RSS between a scene and the same scene at twice the
points, so fixed costs (libraries, buffers) cancel.

Usage: bench/mpm_throughput.py [--steps N] [--out bench/results/mpm_throughput.md]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SOLVER = REPO / "build" / "mpm_solver" / "mpm_solver"

TARGET_RATE = {2: 8.0e6, 3: 3.0e6}  # point-steps/s per core (DEVELOPERS.md)
TARGET_BYTES_PER_POINT = 512


def scene(dim: int, cells_across: int, cell: float) -> str:
    """A block of cells_across^dim cells (2 points per cell axis) in a box 2.5x wider."""
    side = cells_across * cell
    lower = [0.0] * dim
    upper = [2.5 * side] * (dim - 1) + [1.2 * side]
    block_hi = [side] * dim
    vec = lambda v: "[" + ", ".join(f"{x:.6g}" for x in v) + "]"
    return f"""dimension = {dim}
end_time = 100.0
[grid]
cell_size = {cell}
lower = {vec(lower)}
upper = {vec(upper)}
walls = "friction"
wall_friction = 0.4
[output]
progress_interval = 0
[[material]]
name = "sand"
model = "drucker_prager"
youngs_modulus = 1e6
[[block]]
material = "sand"
lower = {vec(lower)}
upper = {vec(block_hi)}
points_per_cell = {2 ** dim}
"""


def run_case(dim: int, cells_across: int, threads: int, steps: int, workdir: Path, end_time: float = 0) -> dict:
    """Runs `steps` steps, or to `end_time` (simulated s) when given."""
    path = workdir / f"scene{dim}d_{cells_across}.toml"
    path.write_text(scene(dim, cells_across, 0.01))
    summary = workdir / "summary.json"
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), OMP_PROC_BIND="close")
    limit = ["--end-time", str(end_time)] if end_time else ["--max-steps", str(steps)]
    subprocess.run([str(SOLVER), str(path), "--no-output", "--quiet", *limit, "--summary", str(summary)],
                   check=True, env=env, stdout=subprocess.DEVNULL)
    return json.loads(summary.read_text())


def collapse_time(cells_across: int, cell: float = 0.01) -> float:
    """Free-fall time of the block's height: by then it is flowing everywhere."""
    return (2.0 * cells_across * cell / 9.81) ** 0.5


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "mpm_throughput.md")
    args = ap.parse_args()
    if not SOLVER.exists():
        sys.exit(f"{SOLVER} is not built; run tools/setup.sh first")

    # ~260k points in 2D and ~220k in 3D: large enough that the grid and points leave the caches.
    sizes = {2: 256, 3: 30}
    rows, raw = [], []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for dim in (2, 3):
            for threads in (1, 2):
                r = run_case(dim, sizes[dim], threads, args.steps, work)
                raw.append(r)
                per_core = r["point_steps_per_second"] / threads
                rows.append((dim, threads, r["points"], r["point_steps_per_second"], per_core))
            small = run_case(dim, sizes[dim], 1, 5, work)
            big = run_case(dim, int(round(sizes[dim] * 2 ** (1 / dim))), 1, 5, work)
            bytes_per_point = (big["peak_rss_bytes"] - small["peak_rss_bytes"]) / (big["points"] - small["points"])
            rows.append((dim, "mem", big["points"], bytes_per_point, None))
            # Whole collapse, one thread: most points yield, so the plastic branch is timed too.
            flow_size = {2: 128, 3: 24}[dim]
            r = run_case(dim, flow_size, 1, 0, work, end_time=collapse_time(flow_size))
            raw.append(r)
            rows.append((dim, "flow", r["points"], r["point_steps_per_second"], r["steps"]))

    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"# MPM throughput ({stamp}, {os.cpu_count()} cores, {args.steps} steps per case)", "",
             "Drucker-Prager sand block collapsing in a box; 2x2 (2D) or 2x2x2 (3D) points per cell.", "",
             "| dim | threads | points | point-steps/s | per core | target per core | ratio to target |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for dim, threads, points, value, per_core in rows:
        if threads in ("mem", "flow"):
            continue
        lines.append(f"| {dim}D | {threads} | {points} | {value / 1e6:.2f} M | {per_core / 1e6:.2f} M | "
                     f"{TARGET_RATE[dim] / 1e6:.0f} M | {per_core / TARGET_RATE[dim]:.2f} |")
    lines += ["", "Whole collapse (block at rest to flowing, most points yielding), 1 thread:", "",
              "| dim | points | steps | point-steps/s | target | ratio |", "| --- | --- | --- | --- | --- | --- |"]
    for dim, kind, points, value, steps in rows:
        if kind == "flow":
            lines.append(f"| {dim}D | {points} | {steps} | {value / 1e6:.2f} M | {TARGET_RATE[dim] / 1e6:.0f} M | "
                         f"{value / TARGET_RATE[dim]:.2f} |")
    lines += ["", "| dim | memory per point (peak RSS slope) | target | ratio |", "| --- | --- | --- | --- |"]
    for dim, threads, points, value, _ in rows:
        if threads == "mem":
            lines.append(f"| {dim}D | {value:.0f} B | {TARGET_BYTES_PER_POINT} B | "
                         f"{value / TARGET_BYTES_PER_POINT:.2f} |")
    two_thread_speedup = {d: [r for r in rows if r[0] == d and r[1] == 2][0][3] /
                          [r for r in rows if r[0] == d and r[1] == 1][0][3] for d in (2, 3)}
    lines += ["", "Two-thread speed-up over one thread, same run: " +
              ", ".join(f"{d}D {s:.2f}x" for d, s in two_thread_speedup.items()), ""]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines))
    args.out.with_suffix(".json").write_text(json.dumps(raw, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
