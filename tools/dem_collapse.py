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

import re
import sys
from dataclasses import dataclass
from pathlib import Path


from column_collapse import published_runout_range
from hgtools import cli, logs
from hgtools.cache import Settled
from hgtools.collapse import Deposit, measure
from hgtools.grains import read_dump
from hgtools.runner import Forms, workdir
from mpm_results import load_run

FORMS = Forms("column_collapse", lammps="dem_2d.lmp", liggghts=None, hybrid=None)   # the hybrid twin is in the deck
DECK = FORMS.deck("lammps")
# the deck's collapse stage runs from the cached column: only what precedes it makes the column
COLLAPSE_STAGE = "label           collapse_stage"


@dataclass(kw_only=True)
class DemResult(Deposit):
    end_time: float                # simulated time at the end (preparation included), s
    length: float                  # domain length (end wall), m
    prepared: bool                 # True if the settled column was built in this run
    steps: int = 0                 # LAMMPS steps of the collapse runs
    loop_time: float = 0.0         # s, LAMMPS's summed loop times of those runs

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


def settled(aspect: float, width: float, d: float, seed: int, extra: dict) -> Settled:
    # the key holds the values as floats: an aspect of 2 (bench/scale_speed.py) and of 2.0 (this
    # driver) are one column, prepared once
    return Settled.entry("dem_column", f"a{aspect:g}_w{width:g}_d{d:g}_s{seed}",
                         dict(a=float(aspect), w=float(width), d=float(d), seed=int(seed), **extra),
                         ((DECK, COLLAPSE_STAGE),), "settled.restart")


def prepare(aspect: float = 2.0, width: float = 0.1, d: float = 0.002, np_: int = 1,
            out: str | Path | None = None, seed: int = 12345, lmp: str = "lmp", timeout: float = 3600,
            extra_vars: dict | None = None, use_cache: bool = True) -> Path:
    """Builds, pours, settles and trims the column with stock LAMMPS (the deck with collapse 0)
    and returns its restart file: the cached one (made and stored if missing), or with
    `use_cache` False a new one in `out`. A caller that times the collapse prepares first, so that
    no collapse runs untimed."""
    extra = {k: str(v) for k, v in (extra_vars or {}).items()}
    cache = settled(aspect, width, d, seed, extra)
    if use_cache and cache.cached():
        return cache.path
    out = workdir(out, f"dem_column_a{aspect:g}")
    target = out / "settled.restart"
    variables = dict(aspect=aspect, width=width, d=d, out=str(out), settled=str(target),
                     prep=1, collapse=0, seed=seed, **extra)
    FORMS.run("lammps", variables, out / "log.lammps", np_=np_, exe=lmp, timeout=timeout).check(
        "to prepare the column", target)
    if not use_cache:
        return target
    cache.store(target)
    return cache.path


END_RE = r"^DEM collapse end: t = (\S+) s, grains \d+, KE/grain = (\S+) J \(rest threshold (\S+) J\)"


def final_continuum(out: Path) -> tuple[dict | None, float | None]:
    """A hybrid's continuum at the end of its run in `out`: its last frame's points ("position",
    "volume") and the grid's cell; (None, None) without frames or grid (a run of grains only).
    Its points are part of the deposit."""
    if not (out / "frames").is_dir():
        return None, None
    frames = load_run(out / "frames")
    if not len(frames) or frames.grid is None:
        return None, None
    return frames.frame(-1, ["position", "volume"]), frames.grid["dx"]


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
    out = workdir(out, f"dem_collapse_a{aspect:g}")
    cache = settled(aspect, width, d, seed, extra)
    prep = not (use_cache and cache.cached())
    target = out / "settled.restart" if prep else cache.path
    variables = dict(aspect=aspect, width=width, d=d, out=str(out), settled=str(target),
                     prep=int(prep), seed=seed, **extra)
    code = "lammps" if hybrid_vars is None else "hybrid"
    if code == "hybrid" and prep:
        # the settled column first, with stock LAMMPS, then the coupled collapse from it
        variables.update(prep=0, settled=str(prepare(aspect, width, d, np_, out, seed, lmp, timeout, extra_vars,
                                                     use_cache)))
    done = FORMS.run(code, variables, out / "log.lammps", hybrid_vars, np_=np_, exe=lmp, timeout=timeout)
    log = done.check("in the collapse", out / "final.dump")   # hybrid_vars may say hybrid 2
    if variables["prep"] and use_cache:
        cache.store(target)
    points, cell = final_continuum(out) if hybrid_vars is not None else (None, None)
    res = measure(read_dump(out / "final.dump"), read_dump(out / "initial.dump"), width, d, points=points, cell=cell)
    m = re.search(END_RE, log, re.M)
    if not m:
        raise RuntimeError(f"no 'DEM collapse end' line in {out / 'log.lammps'}")
    # LAMMPS's loop times of the collapse stage (after the last "collapse_stage" label)
    # (a run from the cached column jumps straight there and may not echo the label)
    steps, loop_time = logs.loops(log, after=COLLAPSE_STAGE)
    return DemResult(aspect=aspect, width=width, d=d, wall_time=done.wall, prepared=prep,
                     length=logs.number(r"^DEM domain length ([-+.\deE]+) m", log),
                     steps=steps, loop_time=loop_time,
                     end_time=float(m.group(1)), ke_per_grain=float(m.group(2)), ke_rest=float(m.group(3)),
                     published=published_runout_range(aspect), log=logs.lines(log, "DEM "), **res)


BED_RE = r"^DEM bed end: t = (\S+) s, grains (\d+), KE/grain = (\S+) J \(rest threshold (\S+) J\)"


@dataclass(kw_only=True)
class BedResult:
    """A settled column kept behind its gate (deck variable gate 1) for a while: is it at rest?"""
    grains: int                    # grains at the end (a hybrid's: those not made points)
    ke_per_grain: float            # J, mean over the second half of the run (the deck's rest measure)
    ke_rest: float                 # J, the deck's rest threshold (1e-5 m g d)
    top_vy: float                  # m/s, mean vertical velocity at the end of the grains in the top 4 d
    wall_time: float               # s


def run_bed(aspect: float = 2.0, width: float = 0.1, d: float = 0.002, np_: int = 1,
            out: str | Path | None = None, seed: int = 12345, tbed: float = 0.2, lmp: str = "lmp",
            timeout: float = 3600, hybrid_vars: dict | None = None) -> BedResult:
    """The settled column (cached, made by run() if missing) kept behind its right wall for `tbed`
    seconds, as pure DEM or (hybrid_vars, e.g. {"hybrid": 2}) coupled: a bed at rest must stay at
    rest. Kinetic energy over the second half of the run, and the creep of the bed's top."""
    out = workdir(out, f"dem_bed_a{aspect:g}")
    cache = settled(aspect, width, d, seed, {})
    if not cache.cached():
        run(aspect=aspect, width=width, d=d, np_=np_, out=out / "prepare", seed=seed, lmp=lmp, timeout=timeout)
    variables = dict(aspect=aspect, width=width, d=d, out=str(out), settled=str(cache.path), prep=0, seed=seed,
                     gate=1, tbed=tbed)
    code = "lammps" if hybrid_vars is None else "hybrid"
    done = FORMS.run(code, variables, out / "log.lammps", hybrid_vars, np_=np_, exe=lmp, timeout=timeout)
    log = done.check("in the bed at rest", out / "final.dump")
    m = re.search(BED_RE, log, re.M)
    if not m:
        raise RuntimeError(f"no 'DEM bed end' line in {out / 'log.lammps'}")
    rows = logs.thermo_rows(log, require="v_kepg")
    late = [r["v_kepg"] for r in rows if r["Time"] >= rows[-1]["Time"] - tbed / 2]
    grains = read_dump(out / "final.dump")
    moving = grains["type"] == 1
    y, vy = grains["y"][moving], grains["vy"][moving]
    top = y > y.max() - 4 * d
    return BedResult(grains=int(m.group(2)), ke_per_grain=sum(late) / len(late), ke_rest=float(m.group(4)),
                     top_vy=float(vy[top].mean()), wall_time=done.wall)


def run_from_settled(**kwargs) -> DemResult:
    """run(), with the collapse always from the cached settled column, as the hybrid twins start:
    the first run after a preparation collapses from the state in memory, which a restart file
    does not reproduce to the last bit (and a chaotic collapse amplifies that)."""
    res = run(**kwargs)
    return run(**kwargs) if res.prepared else res


def main(argv=None) -> int:
    p = cli.scene_parser(__doc__, 12345, dict(aspect=(2.0, "H0/L0"), width=(0.1, "L0, m"),
                                              d=(0.002, "mean grain diameter, m")),
                         cache="column", var="deck variable (mu, e, knfac, dtdiv, ketol, rho, ...)")
    a = cli.parse(p, argv)
    res = run(a.aspect, a.width, a.d, a.np_, a.out, a.seed, not a.no_cache, extra_vars=a.var)
    cli.print_result(res, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
