#!/usr/bin/env python3
"""Pure-DEM reference of the planar granular column collapse (docs/design.md sections 3 and 6).

Runs input_decks/column_collapse/dem_2d.lmp with Debian's stock LAMMPS (`lmp`), reads the
final dump and measures the normalised runout (Lf - L0)/L0 and the final surface profile,
for comparison with the published laws (tools/column_collapse.published_runout_range).

The settled column (pouring + settling + trimming, about half of the cost) is cached per
parameter set in $HYBRID_CACHE/dem_column/ (default ~/.cache/hybrid-granular/dem_column/),
so repeated runs only redo the collapse.

Front definition (documented choice). The deposit front Lf is the right end of the grain
pile that is connected, through contacts, to the grains at the back wall: grains (flowing
ones only, not the frozen floor) are linked when their gap is below 5 % of d, the cluster
holding the grain nearest to x = 0 is the deposit, and Lf = max(x + r) over it. A single
chain of grains lying on the floor still counts ("at least one grain thick"); grains that
rolled away and stopped apart from the pile do not. The 99.5th percentile of x + r and
the plain maximum are reported alongside for reference.

    tools/dem_collapse.py --aspect 2 --width 0.1 --d 0.002 --np 2 --out /tmp/dem_a2
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DECK = REPO / "input_decks" / "column_collapse" / "dem_2d.lmp"
sys.path.insert(0, str(Path(__file__).resolve().parent))
from column_collapse import published_runout_range  # noqa: E402

CONTACT_GAP = 0.05       # grains closer than this fraction of d are in contact (front cluster)


def cache_root() -> Path:
    base = os.environ.get("HYBRID_CACHE", str(Path.home() / ".cache" / "hybrid-granular"))
    return Path(base) / "dem_column"


@dataclass
class DemResult:
    aspect: float
    width: float
    d: float
    grains: int
    runout: float                  # (Lf - L0)/L0, front = connected deposit
    runout_p995: float             # front = 99.5th percentile of x + r
    runout_max: float              # front = max x + r over all grains
    front: float                   # Lf, m
    height: float                  # initial column height (max y + r), m
    final_height: float            # final deposit height at the wall (max y + r), m
    max_speed: float               # final, m/s, all flowing grains
    max_speed_deposit: float       # final, m/s, grains of the connected deposit
    max_overlap_initial: float     # largest overlap / d in the settled column
    max_overlap_final: float       # largest overlap / d in the deposit
    detached: int                  # grains outside the connected deposit
    ke_per_grain: float            # final mean kinetic energy per grain, J
    ke_rest: float                 # the deck's rest threshold on it, J
    end_time: float                # simulated time at the end (preparation included), s
    length: float                  # domain length (end wall), m
    wall_time: float               # s, this run (collapse, plus preparation if not cached)
    prepared: bool                 # True if the settled column was built in this run
    steps: int = 0                 # LAMMPS steps of the collapse runs
    loop_time: float = 0.0         # s, LAMMPS's summed loop times of those runs
    published: tuple = ()
    profile: list = field(default_factory=list)   # [(x_centre, surface height)] per bin, connected deposit only
    log: str = ""

    @property
    def at_rest(self) -> bool:
        return self.ke_per_grain < self.ke_rest

    def summary(self) -> str:
        lo, hi = self.published
        rel = "inside" if lo <= self.runout <= hi else (
            f"{100 * (self.runout / hi - 1):+.1f} % above the upper bound" if self.runout > hi
            else f"{100 * (self.runout / lo - 1):+.1f} % below the lower bound")
        return (f"DEM column a = {self.aspect:g} (L0 = {self.width:g} m, H0 = {self.height:.4g} m, "
                f"d = {self.d:g} m): {self.grains} grains, wall time {self.wall_time:.1f} s"
                f"{' (incl. preparation)' if self.prepared else ' (settled column cached)'}\n"
                f"  (Lf - L0)/L0 = {self.runout:.3f} (connected front; 99.5 % {self.runout_p995:.3f}, "
                f"max {self.runout_max:.3f}, {self.detached} detached grains)\n"
                f"  published {lo:.2f} .. {hi:.2f}: {rel}\n"
                f"  final height at wall {self.final_height:.4g} m (H/H0 = {self.final_height / self.height:.3f}),"
                f" KE/grain {self.ke_per_grain:.2e} J (rest < {self.ke_rest:.2e}),\n"
                f"  max speed {self.max_speed:.2e} m/s (deposit {self.max_speed_deposit:.2e} m/s), max overlap/d settled {self.max_overlap_initial:.4f},"
                f" final {self.max_overlap_final:.4f}")


def read_dump(path: Path) -> dict:
    """A single-frame LAMMPS custom dump as a dict of numpy columns."""
    lines = Path(path).read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("ITEM: ATOMS"))
    cols = lines[i].split()[2:]
    data = np.loadtxt(lines[i + 1:], ndmin=2)
    return {c: data[:, k] for k, c in enumerate(cols)}


def contact_pairs(pos, r, cutoff, period_z=None):
    """Index pairs (i < j) with gap (centre distance - r_i - r_j) below cutoff, and the gaps.
    pos: N x 2 or N x 3 centres; a numpy cell list over x and y; period_z: the period of a
    periodic z (minimum image), or None."""
    pos = np.asarray(pos, dtype=float)
    n = len(pos)
    cell = 2 * r.max() + cutoff
    ix = np.floor((pos[:, 0] - pos[:, 0].min()) / cell).astype(np.int64)
    iy = np.floor((pos[:, 1] - pos[:, 1].min()) / cell).astype(np.int64)
    ny = iy.max() + 3
    key = ix * ny + iy
    order = np.argsort(key)
    skey = key[order]
    out_i, out_j = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            nkey = (ix + dx) * ny + (iy + dy)
            lo = np.searchsorted(skey, nkey, "left")
            hi = np.searchsorted(skey, nkey, "right")
            counts = hi - lo
            if counts.sum() == 0:
                continue
            ii = np.repeat(np.arange(n), counts)
            jj = order[np.concatenate([np.arange(a, b) for a, b in zip(lo, hi)])]
            keep = ii < jj
            out_i.append(ii[keep])
            out_j.append(jj[keep])
    i = np.concatenate(out_i)
    j = np.concatenate(out_j)
    delta = pos[i] - pos[j]
    if period_z is not None:
        delta[:, 2] -= period_z * np.round(delta[:, 2] / period_z)
    gap = np.linalg.norm(delta, axis=1) - r[i] - r[j]
    keep = gap < cutoff
    return i[keep], j[keep], gap[keep]


def dump_positions(dump: dict) -> np.ndarray:
    """Centres of a dump as N x 2 (x, y) or N x 3 when it has z."""
    return np.column_stack([dump[c] for c in ("x", "y", "z") if c in dump])


def max_overlap(dump: dict, d: float, period_z=None) -> float:
    """Largest grain-grain overlap (including the floor grains), as a fraction of d."""
    _, _, gap = contact_pairs(dump_positions(dump), dump["radius"], 0.0, period_z)
    return float(max(0.0, -gap.min())) / d if len(gap) else 0.0


def connected_deposit(pos, r, d, period_z=None) -> np.ndarray:
    """Boolean mask of the grains connected, through contacts (gap < CONTACT_GAP d), to the
    grain nearest the back wall (pos: N x 2 or N x 3 centres)."""
    pos = np.asarray(pos, dtype=float)
    n = len(pos)
    i, j, _ = contact_pairs(pos, r, CONTACT_GAP * d, period_z)
    parent = np.arange(n)

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in zip(i.tolist(), j.tolist()):
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    roots = np.array([find(a) for a in range(n)])
    return roots == roots[np.argmin(pos[:, 0])]


def surface_profile(x, y, r, bin_width, length):
    """Final free-surface height max(y + r) per x bin of width bin_width (NaN: empty)."""
    edges = np.arange(0.0, length + bin_width, bin_width)
    idx = np.clip(np.digitize(x, edges) - 1, 0, len(edges) - 2)
    top = np.full(len(edges) - 1, np.nan)
    np.fmax.at(top, idx, y + r)
    centres = 0.5 * (edges[:-1] + edges[1:])
    return [(float(c), float(h)) for c, h in zip(centres, top) if np.isfinite(h)]


def analyse(final: dict, initial: dict, aspect: float, width: float, d: float) -> dict:
    grains = final["type"] == 1
    x, y, r = final["x"][grains], final["y"][grains], final["radius"][grains]
    mask = connected_deposit(np.column_stack([x, y]), r, d)
    edge = x + r
    front = float(edge[mask].max())
    gi = initial["type"] == 1
    height = float((initial["y"][gi] + initial["radius"][gi]).max())
    near_wall = x < 2 * d
    speed = np.hypot(final["vx"][grains], final["vy"][grains])
    return dict(
        grains=int(grains.sum()),
        runout=(front - width) / width,
        runout_p995=(float(np.percentile(edge, 99.5)) - width) / width,
        runout_max=(float(edge.max()) - width) / width,
        front=front,
        height=height,
        # 0 when no grain is at the wall (a hybrid whose continuum fills the corner)
        final_height=float(np.max((y + r)[near_wall], initial=0.0)),
        max_speed=float(speed.max()),
        max_speed_deposit=float(speed[mask].max()),
        max_overlap_initial=max_overlap(initial, d),
        max_overlap_final=max_overlap(final, d),
        detached=int((~mask).sum()),
        profile=surface_profile(x[mask], y[mask], r[mask], 2 * d, front),  # the deposit, as the runout
    )


def settled_path(aspect: float, width: float, d: float, seed: int, extra: dict) -> Path:
    deck_hash = hashlib.sha1(DECK.read_bytes()).hexdigest()[:10]
    tag = json.dumps(dict(a=aspect, w=width, d=d, seed=seed, **extra), sort_keys=True)
    key = hashlib.sha1(tag.encode()).hexdigest()[:10]
    return cache_root() / f"a{aspect:g}_w{width:g}_d{d:g}_s{seed}_{key}_{deck_hash}" / "settled.restart"


def run_lammps(deck: Path, variables: dict, log: Path, np_: int, lmp: str, timeout: float,
               hybrid: bool = False) -> tuple[subprocess.CompletedProcess, float]:
    """Runs `deck` with `variables` (-var NAME VALUE), its log in `log`: stock LAMMPS on np_
    ranks (tools/mpirun.sh), or coupled through tools/hybrid_launch.py. Returns the completed
    process and its wall time."""
    args = ["-log", str(log), "-screen", "none"]
    for k, v in variables.items():
        args += ["-var", k, str(v)]
    if hybrid:
        cmd = [sys.executable, str(REPO / "tools" / "hybrid_launch.py"), "-np", str(np_), str(deck)] + args
    else:
        cmd = [lmp, "-in", str(deck)] + args
        if np_ > 1:
            cmd = [str(REPO / "tools" / "mpirun.sh"), "-np", str(np_)] + cmd
    t0 = time.time()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    return proc, time.time() - t0


def _lammps(variables: dict, out: Path, np_: int, lmp: str, timeout: float,
            hybrid: bool = False) -> tuple[subprocess.CompletedProcess, float]:
    return run_lammps(DECK, variables, out / "log.lammps", np_, lmp, timeout, hybrid)


def run(aspect: float = 2.0, width: float = 0.1, d: float = 0.002, np_: int = 1,
        out: str | Path | None = None, seed: int = 12345, use_cache: bool = True,
        lmp: str = "lmp", timeout: float = 3600, extra_vars: dict | None = None,
        hybrid_vars: dict | None = None) -> DemResult:
    """Runs the DEM column collapse and returns the measured result.

    hybrid_vars: run the collapse coupled (the deck's hybrid twin, `hybrid 1`, or with
    hybrid=2 the adaptive one) with these extra deck variables (hx, hy, hcell, hevery, hyoungs,
    hphi, hadapt, hdepth, hband); the settled column is the
    same as the pure DEM run's (built with stock LAMMPS if not cached). The result then
    holds the grains only; the continuum's points are in <out>/frames (HDF5)."""
    extra = {k: str(v) for k, v in (extra_vars or {}).items()}
    out = Path(out) if out else Path.cwd() / f"dem_collapse_a{aspect:g}"
    out.mkdir(parents=True, exist_ok=True)
    settled = settled_path(aspect, width, d, seed, extra)
    prep = not (use_cache and settled.exists())
    if prep:
        settled.parent.mkdir(parents=True, exist_ok=True)
        target = out / "settled.restart"
    else:
        target = settled
    variables = dict(aspect=aspect, width=width, d=d, out=str(out), settled=str(target),
                     prep=int(prep), seed=seed, **extra)
    hybrid = hybrid_vars is not None
    if hybrid and prep:
        # the settled column first, with stock LAMMPS, then the coupled collapse from it
        proc, _ = _lammps(dict(variables, collapse=0), out, np_, lmp, timeout)
        if proc.returncode != 0 or not target.exists():
            raise RuntimeError(f"LAMMPS failed to prepare the column ({proc.returncode}):\n{proc.stderr[-2000:]}")
        variables["prep"] = 0
    if hybrid:
        variables["hybrid"] = 1  # hybrid_vars may say 2 (adaptive zones)
        variables.update({k: str(v) for k, v in hybrid_vars.items()})
    proc, wall = _lammps(variables, out, np_, lmp, timeout, hybrid)
    log = (out / "log.lammps").read_text() if (out / "log.lammps").exists() else ""
    if proc.returncode != 0 or not (out / "final.dump").exists():
        tail = "\n".join(log.splitlines()[-30:])
        raise RuntimeError(f"LAMMPS failed ({proc.returncode}): {' '.join(map(str, proc.args))}\n{proc.stdout[-2000:]}"
                           f"\n{proc.stderr[-2000:]}\n{tail}")
    if prep and use_cache:
        shutil.copyfile(target, settled)
    res = analyse(read_dump(out / "final.dump"), read_dump(out / "initial.dump"), aspect, width, d)
    lines = [ln for ln in log.splitlines() if ln.startswith("DEM ")]
    m = re.search(r"^DEM collapse end: t = (\S+) s, grains \d+, KE/grain = (\S+) J \(rest threshold (\S+) J\)",
                  log, re.M)
    if not m:
        raise RuntimeError(f"no 'DEM collapse end' line in {out / 'log.lammps'}")
    length = float(re.search(r"^DEM domain length ([-+.\deE]+) m", log, re.M).group(1))
    # LAMMPS's loop times of the collapse stage (after the last "collapse_stage" label)
    # (a run from the cached column jumps straight there and may not echo the label)
    stage = log[max(0, log.rfind("label           collapse_stage")):]
    loops = re.findall(r"^Loop time of (\S+) on \d+ procs for (\d+) steps", stage, re.M)
    steps, loop_time = sum(int(n) for _, n in loops), sum(float(t) for t, _ in loops)
    return DemResult(aspect=aspect, width=width, d=d, wall_time=wall, prepared=prep, length=length,
                     steps=steps, loop_time=loop_time,
                     end_time=float(m.group(1)), ke_per_grain=float(m.group(2)), ke_rest=float(m.group(3)),
                     published=published_runout_range(aspect), log="\n".join(lines), **res)


def run_from_settled(**kwargs) -> DemResult:
    """run(), with the collapse always from the cached settled column, as the hybrid twins start:
    the first run after a preparation collapses from the state in memory, which a restart file
    does not reproduce to the last bit (and a chaotic collapse amplifies that)."""
    res = run(**kwargs)
    return run(**kwargs) if res.prepared else res


def add_run_arguments(parser: argparse.ArgumentParser, settled: str) -> None:
    """The options every 2D scene driver has: ranks, output, seed and the settled-state cache."""
    parser.add_argument("--np", type=int, default=1, dest="np_", help="MPI ranks (tools/mpirun.sh)")
    parser.add_argument("--out", default=None, help="output directory")
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument("--no-cache", action="store_true", help=f"rebuild the settled {settled}")


def deck_vars(parser: argparse.ArgumentParser, items: list, option: str = "--var") -> dict:
    """The NAME=VALUE items of a repeatable command-line option as deck variables; a malformed
    item is a usage error naming it (the scene drivers share this)."""
    variables = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            parser.error(f"{option} {item!r}: expected NAME=VALUE")
        variables[name] = value
    return variables


def print_result(res, as_json: bool, **derived) -> None:
    """A scene driver's result: its fields (and derived figures) as JSON, or its LAMMPS log
    excerpt and summary."""
    if as_json:
        print(json.dumps(dict(res.__dict__, **derived), indent=1, default=str))
    else:
        print(res.log)
        print(res.summary())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--aspect", type=float, default=2.0, help="H0/L0")
    p.add_argument("--width", type=float, default=0.1, help="L0, m")
    p.add_argument("--d", type=float, default=0.002, help="mean grain diameter, m")
    add_run_arguments(p, "column")
    p.add_argument("--var", action="append", default=[], metavar="NAME=VALUE",
                   help="extra deck variable (mu, e, knfac, dtdiv, ketol, rho, ...)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    a = p.parse_args(argv)
    res = run(a.aspect, a.width, a.d, a.np_, a.out, a.seed, not a.no_cache, extra_vars=deck_vars(p, a.var))
    print_result(res, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
