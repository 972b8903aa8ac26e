#!/usr/bin/env python3
"""Speed of the hybrid against pure LAMMPS DEM as the scene grows (issue 15), side by side in one
invocation, with a cost model that predicts it.

Scene: the deep 2D silo (input_decks/silo/dem_2d.lmp and its adaptive twin hybrid_2d.lmp), every
length in grain diameters so that only the size changes between sizes: width W = n d, fill
height H = 3 W, orifice D = 10 d, d = 2 mm (3 n^2 d^2 at 82 % packing holds about 3.1 n^2 disks:
n = 40, 90, 160 give about 5k, 25k and 80k disks). Each size runs the discharge as pure
DEM and as the hybrid from the same cached settled silo, on the same LAMMPS ranks; the hybrid's
MPM process (OpenMP, default threads) runs only while LAMMPS waits for it, so both use the same
cores. The DEM and its hybrids run in the same minutes, one at a time (tools/hgtools/interleave.py:
quanta of 5 s, each to the run least far along its discharge record), so that a machine whose speed
drifts slows them alike (the runs one after the other, until 2026-11-28, gave the 80k silo's DEM
chunks 37-79 s); a run's time is the sum of its quanta. The hybrid uses the fix's grid from the grains (`hcell 0`: 6 d cells, 2x2 points, about
9 disks per point) unless --hcell says otherwise.

Measures, per size: the DEM's and the hybrid's wall times of the discharge, counting only the
quanta in which each ran (speedup = DEM over hybrid), the steady discharge rate of each (error = hybrid over DEM - 1, ± its standard error from the
two runs' own fluctuation, hgtools.discharge.rate_standard_error; beside it the same for the grains
counted, since a hybrid's grains may carry more or less than their solid mass), the continuum's share
of the material (1 - the grains' carried mass over the total, f_couple[8], averaged over the
thermo rows), and the hybrid's time ledger (entries 30-32: coupling, MPM wait, rezones), scaled to
the time the hybrid ran (Outcome.running_share; docs/design.md 7.3).

Cost model (docs/design.md section 7.3): a DEM step costs c_g per grain in LAMMPS (measured on
this size's DEM run: its loop time over its grain-steps); the hybrid's step costs f c_g per grain
still in LAMMPS, f = 1 - s + s n_h / n_d with s the DEM's Pair share of its loop and n the neighbours
per grain of each run (LAMMPS's own counts: the hybrid's surface and deposit grains have fewer),
plus the MPM process's c_p per point-substep (bench/results/mpm_throughput.json, 2D, the threads
it runs with) while LAMMPS waits, plus c_x per coupled grain and exchange
(bench/results/coupling_overhead.json: the fix's cost per exchange, less its MPM substep, over its
coupled grains).
predicted speedup = T_DEM / (f c_g * grain-steps + c_p * point-substeps + c_x * coupled grain-
exchanges), all counts from the hybrid's own thermo rows. Where the measured speedup falls more
than 20 % short of it, the rest is overhead the model does not hold (rezones, oracle, waiting).

The 3D silo (tools/dem3d_silo.py and its twin hybrid_3d.lmp) is scaled the same way: square section
W = n d, H = 3 W, circular orifice D = 6 d (about 3.1 n^3 spheres: n = 12, 18, 26 give about 5k, 18k and
55k); its hybrid at the fix's zones (grid from the grains: 4 d cells, 2^3 points of about 9 spheres), the
four side walls touched, exchange every 10 steps; the cost model with the 3D MPM's cost per point;
--liggghts discharges each packing with pure LIGGGHTS too, the DEM's own noise floor. The grains the
zones keep near the floor, over the orifice and under the free surface fill about 40 d of the height
whatever the width, so at H = 3 W LAMMPS's share falls only slowly with size; --silo3d-depth sets H / W
for a deep bin of the same section (e.g. 10: W = 20 d, H = 200 d, about 98k spheres, whose preparation
alone is over an hour here: a pour of 40,000 steps, then settle loops of 4,000 steps at about 2 min each;
`--prepare` caches it beside other work that does not run coupled jobs, which starve beside it).

Second scene: the 2D column collapse, a = 2, L0 = n d (input_decks/column_collapse/dem_2d.lmp with
`hybrid 2`, `hcell 0`): the DEM and the adaptive hybrid collapse from the same cached column to
rest; error = the final surface's RMS over H0, and the runout's relative error (the two in turns of
5 s, as a collapse has no record of how far it is). --collapse-touch adds the hybrid whose continuum
may touch the back wall and the floor (deck variable htouch 1), in the same turns against the same DEM.
--collapse-touch-only runs that one alone against the DEM (the untouched hybrid's rest at 100 d is fragile:
2.65x the DEM's steps on 2026-12-04, a slow slump of its heap, bench/results/deposit_rest.md).

Silo rows may also run the hybrid at other zone depths (--depths, grain diameters) against the same
DEM run: the error against wall time as the continuum comes closer to the free surface, the floor
and the orifice's region (the third panel of the plot); --surface-depths moves it closer to the free
surface only (fix keyword surface_depth), the floor and the orifice's region keeping the fix's depth.

Cost on this 2-core machine: a size's settled silo is prepared once per machine (~/.cache/hybrid-
granular) and its preparation is not timed (`--prepare` does only that, and may share the machine), but
it is long at 160 d: the pour alone is 289,106 steps of 87,210 disks (about 65 min alone).
Since the deck's settle loops have a drag (2026-11-27, docs/design.md 3.4) the fill rests 4 loops of
0.02 s after the pour (t = 0.84 s; without it, it still swung between 3e-9 and 2e-8 J per grain against
the threshold of 1.5e-9 J 12 loops in), then the trim, 0.05 s and one loop: 79,627 disks at rest at
t = 0.911 s, about 10 min of settling alone (the whole preparation took 7,950 s on 2026-11-27, a test
suite running beside it for the first 6,060 s). With the DEM's 1 s of discharge and two
hybrids, `--sizes 160` then needs about 55 min alone on a fast day (the DEM ~43 min) and took 2 h on
2026-11-28 (the DEM 99 min, its speed drifting 2x between chunks: compare the model's prediction).

Usage: bench/scale_speed.py [--np 2] [--threads 2] [--sizes 40,90,160] [--silo3d-sizes 12,18,26] [--silo3d-depth 3] [--liggghts]
                            [--collapse-sizes 50,100,200] [--collapse-touch | --collapse-touch-only | --collapse-depths-only]
                            [--collapse-depths 9,12] [--collapse-every 20,40] [--depths 12,24] [--surface-depths 12] [--keep]
       bench/scale_speed.py --render     (the report and plot again from the JSON)
       bench/scale_speed.py --prepare --sizes 160   (only the settled silos, cached; not timed)
Writes bench/results/scale_speed.json (a list `rows`, one per scene, size and cores at the fix's zones,
and `depth_front`, the depth variants), scale_speed.md and scale_speed.png; the notes
below the marker in scale_speed.md are kept (hgtools.report).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
from dataclasses import replace
from datetime import datetime, timezone
from functools import partial
from itertools import product
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from column_collapse import combine_surfaces, points_surface, surface_error  # noqa: E402
from dem_collapse import final_continuum, prepare as prepare_column, run as collapse  # noqa: E402
import dem3d_silo  # noqa: E402
from dem_silo import prepare_silo, run_dem_silo  # noqa: E402
from hgtools.discharge import rate_ratio_se, recorded_time  # noqa: E402
from hgtools.interleave import Job, interleave, no_progress  # noqa: E402
from hgtools import logs  # noqa: E402
from hgtools.logs import thermo_rows  # noqa: E402
from hgtools.report import write_report  # noqa: E402

RESULTS = REPO / "bench" / "results"
D = 0.002                     # grain diameter, m
ORIFICE = 10                  # orifice width, d
ORIFICE_3D = 6                # orifice diameter of the 3D silo, d (the reduced 3D silo's, tests/test_dem3d_silo.py)
DEPTH = 3                     # fill height over width
ASPECT = 2                    # the collapse's H0 / L0
EVERY = 10                    # the hybrids' exchange interval (hybrid_2d.lmp's default; hybrid_3d.lmp's is 20)
QUANTUM = 5.0                 # s, how long one run of a comparison runs before the next may (hgtools.interleave)
MAX_STOP = 120.0              # s, the longest a run waits stopped while the others catch up with it
REPLY_TIMEOUT = 600.0         # s, the silo hybrids' fix keyword timeout (deck variable htimeout): > MAX_STOP


def silo_size(n: int, orifice: int = ORIFICE, depth: float = DEPTH) -> dict:
    """The silo of width n d and fill height depth x n d, in metres."""
    return dict(width=n * D, height=depth * n * D, orifice=orifice * D, d=D)


def mpm_point_cost(threads: int, dim: int = 2) -> float:
    """s per point-substep of the MPM at `threads` threads (bench/results/mpm_throughput.json)."""
    rows = json.loads((RESULTS / "mpm_throughput.json").read_text())
    best = [r for r in rows if r["dimension"] == dim and r["threads"] == threads and "grid_nodes" in r]
    return 1.0 / max(r["point_steps_per_second"] for r in best)


def exchange_cost() -> float:
    """s per coupled grain and exchange on the DEM side: the fix's cost per exchange in
    bench/results/coupling_overhead.json (every 10), less its points' MPM substeps (one thread),
    over its coupled grains."""
    case = json.loads((RESULTS / "coupling_overhead.json").read_text())["summary"]["np1_coupled_every10"]
    mpm = case["points"] * case["substeps_per_exchange"] * mpm_point_cost(1)
    return (1e-3 * case["fix_ms_per_exchange"] - mpm) / case["coupled_grains"]


def neighbour_factor(dem_text: str, hyb_text: str) -> tuple[float, list[float]]:
    """The hybrid's cost per grain-step over the DEM's, from their logs: LAMMPS's Pair work is per
    neighbour (its share of the DEM's loop scales with the neighbours per grain), the rest per grain.
    The hybrid's grains (a surface layer, the band, a thin deposit) have fewer neighbours each than a
    dense bed's (the 200 d collapse: 2.0 against 2.6). Returns the factor and the [DEM, hybrid]
    neighbours per grain; 1 where a log has no run's neighbour count."""
    dem, hyb = logs.neighbours(dem_text), logs.neighbours(hyb_text)
    if not (dem["atom_steps"] > 0 and hyb["atom_steps"] > 0 and dem["loop_s"] > 0 and dem["neighbour_steps"] > 0):
        return 1.0, []
    per_grain = [dem["neighbour_steps"] / dem["atom_steps"], hyb["neighbour_steps"] / hyb["atom_steps"]]
    pair_share = min(1.0, dem["pair_s"] / dem["loop_s"])
    return 1.0 - pair_share + pair_share * per_grain[1] / per_grain[0], per_grain


def steps_weighted(rows: list[dict], key) -> float:
    """Sum over the thermo intervals of (steps in the interval) x key(row at its end)."""
    steps = np.diff([r["Step"] for r in rows])
    return float(sum(s * key(r) for s, r in zip(steps, rows[1:])))


def hybrid_ledger(log: Path, every: int) -> dict:
    """The counts the cost model needs and the continuum's share, from the hybrid's thermo rows."""
    rows = thermo_rows(log, require="f_couple[8]")
    total = np.array([r["f_couple[8]"] for r in rows])
    share = 1.0 - np.array([r["v_mgrains"] for r in rows]) / np.where(total > 0, total, 1.0)
    return dict(
        grain_steps=steps_weighted(rows, lambda r: r["v_ng"]),
        point_substeps=steps_weighted(rows, lambda r: r["f_couple[3]"] * r["f_couple[6]"] / every),
        coupled_exchanges=steps_weighted(rows, lambda r: r["f_couple[2]"] / every),
        share_mean=float(share[1:].mean()), share_t=[r["Time"] for r in rows], share=share.tolist(),
        points_max=int(max(r["f_couple[3]"] for r in rows)), coupling_s=rows[-1]["f_couple[30]"],
        mpm_wait_s=rows[-1]["f_couple[31]"], rezone_s=rows[-1]["f_couple[32]"])


def side_by_side(runs: list[tuple[str, callable, Path | None]]) -> list[tuple]:
    """The runs of one comparison (name, the call, its discharge record or None) in the same
    minutes, one at a time (hgtools.interleave: each quantum to the run least far along its record,
    in turns without one), and for each its result, its wall and loop time made the time it ran,
    the CPU seconds its processes used (the steadier measure of the work on a shared machine) and
    the share of its loop time in which it ran (Outcome.running_share: it scales the fix's time
    ledger, which counts the stops)."""
    for _, _, record in runs:
        if record is not None:
            record.unlink(missing_ok=True)    # a former run's record is no measure of this one's progress
    jobs = [Job(name, run, no_progress if record is None else partial(recorded_time, record))
            for name, run, record in runs]
    return [(replace(o.result, wall_time=o.running(o.result.wall_time), loop_time=o.running(o.result.loop_time)),
             o.cpu_s, o.running_share(o.result.loop_time)) for o in interleave(jobs, quantum=QUANTUM, max_stop=MAX_STOP)]


def cost_model(dem_loop: float, dem_log: Path, hyb_log: Path, threads: int, dim: int = 2, every: int = EVERY,
               running: float = 1.0) -> dict:
    """The cost model's terms and prediction (module docstring), and the hybrid's ledger (`every`:
    its exchange interval, steps; `running`: the hybrid's running fraction, which scales its
    ledger's wall times to the time it ran)."""
    dem_rows = thermo_rows(dem_log, require="v_ng")
    c_g = dem_loop / steps_weighted(dem_rows, lambda r: r["v_ng"])
    led = hybrid_ledger(hyb_log, every=every)
    c_p, c_x = mpm_point_cost(threads, dim), exchange_cost()
    grain_factor, neighbours = neighbour_factor(Path(dem_log).read_text(), Path(hyb_log).read_text())
    model = dict(grains=c_g * grain_factor * led["grain_steps"], points=c_p * led["point_substeps"],
                 exchange=c_x * led["coupled_exchanges"])
    return dict(predicted_speedup=dem_loop / sum(model.values()), continuum_share=led["share_mean"],
                cost_per_grain_step_s=c_g, grain_cost_factor=grain_factor, neighbours_per_grain=neighbours,
                cost_per_point_substep_s=c_p, cost_per_coupled_grain_exchange_s=c_x,
                model_s=model, coupling_s=running * led["coupling_s"], mpm_wait_s=running * led["mpm_wait_s"],
                rezone_s=running * led["rezone_s"], ledger_running_fraction=running, points_max=led["points_max"],
                share_t=led["share_t"], share=led["share"])


def speeds(dem, hyb, dem_cpu: float, hyb_cpu: float) -> dict:
    return dict(speedup=dem.wall_time / hyb.wall_time, loop_speedup=dem.loop_time / hyb.loop_time,
                cpu_speedup=dem_cpu / hyb_cpu, dem_cpu_s=dem_cpu, hybrid_cpu_s=hyb_cpu, dem_wall_s=dem.wall_time,
                hybrid_wall_s=hyb.wall_time, dem_loop_s=dem.loop_time, hybrid_loop_s=hyb.loop_time)


# the zone variants a silo row may run: key of the row -> deck variable, run name, label, and whether
# the value is a length in grain diameters (the deck wants metres) or a choice (htouch: 2 = the
# side walls and the floor, the region over the orifice discrete)
VARIANTS = {"depth_d": ("hdepth", "depth", "depth", True),
            "surface_depth_d": ("hsurface", "surface", "surface depth", True),
            "touch": ("htouch", "touch", "touch", False),
            "every": ("hevery", "every", "exchange every", False)}


# the packing of rows without a seed (before 2026-12-07 every row was the --seed default's)
DEFAULT_SEED = 12345


def row_key(r: dict) -> tuple:
    """What a row measures: a rerun replaces the saved row with the same key (another packing, its
    `seed`, is another row)."""
    return (r["scene"], r["width_d"], r.get("height_d"), r["cores"], r.get("pinned", False),
            r.get("seed", DEFAULT_SEED), *(r.get(k) for k in VARIANTS))


def is_variant(r: dict) -> bool:
    """A row of the hybrid at other zones than the fix's, or another exchange interval (the JSON's
    `depth_front`)."""
    return any(r.get(key) is not None for key in VARIANTS)


def variant_value(value) -> str:
    return value if isinstance(value, str) else f"{value:g}"    # every auto


def variant_label(r: dict, unit: str = " d") -> str:
    return ", ".join(f"{VARIANTS[key][2]} {variant_value(r[key])}{unit if VARIANTS[key][3] else ''}"
                     for key in VARIANTS if r.get(key) is not None)


def exchange_interval(hvars: dict, log: Path) -> int:
    """The hybrid's exchange interval: the deck variable's, or with every auto the one the fix chose."""
    every = str(hvars.get("hevery", EVERY))
    if every != "auto":
        return int(every)
    m = re.search(r"^fix hybrid/mpm: exchange every (\d+) step\(s\) \(every auto", log.read_text(), re.M)
    if not m:
        raise RuntimeError(f"no 'exchange every N step(s) (every auto' line in {log}")
    return int(m.group(1))


class Silo:
    """A deep silo scene: its size in grain diameters, how to prepare its packing (cached) and
    run it as DEM or hybrid, and the hybrid's deck variables for the fix's zones."""
    scene: str
    dim: int
    orifice_d: int
    log: str                       # the LAMMPS log a run writes in its directory

    def __init__(self, np_: int, seed: int, tdis: float, hcell: str, depth: float = DEPTH, **hybrid_vars):
        self.common = dict(np_=np_, seed=seed, tdis=tdis, fstop=0.9, timeout=4 * 3600)
        self.hybrid_vars = dict(hcell=hcell, **hybrid_vars)
        self.depth = depth    # fill height over width

    def size(self, n: int) -> dict:
        return silo_size(n, self.orifice_d, self.depth)


class Silo2d(Silo):
    """The deep 2D silo (tools/dem_silo.py; hybrid_2d.lmp's zones are the fix's with hcell 0)."""
    scene, dim, orifice_d, log = "silo_2d", 2, ORIFICE, "log.lammps"

    def prepare(self, n: int, work: Path) -> None:    # cached
        size = self.size(n)
        prepare_silo(size["width"], size["height"], D, self.common["seed"], work / f"prep_{n}",
                     np_=self.common["np_"], timeout=self.common["timeout"])

    def run(self, n: int, out: Path, hybrid_vars: dict | None = None):
        return run_dem_silo(out=out, hybrid_vars=hybrid_vars, **self.size(n), **self.common)


class Silo3d(Silo):
    """The deep 3D silo of square section and circular orifice (tools/dem3d_silo.py, H = 3 W, D = 6 d).
    Its hybrid twin (hybrid_3d.lmp) runs at the fix's zones: the grid from the grains (4 d cells),
    depth and band the fix's, the four side walls touched, exchange every EVERY steps."""
    scene, dim, orifice_d, log = "silo_3d", 3, ORIFICE_3D, "log.txt"

    def __init__(self, np_: int, seed: int, tdis: float, hcell: str, depth: float = DEPTH):
        super().__init__(np_, seed, tdis, hcell, depth, hevery=EVERY, hdepth=0, hband=0, htouch=1)

    def prepare(self, n: int, work: Path) -> None:    # cached
        size = self.size(n)
        dem3d_silo.prepare(size["width"], size["height"], size["orifice"], D, self.common["seed"], {},
                           self.common["np_"], timeout=self.common["timeout"])

    def run(self, n: int, out: Path, hybrid_vars: dict | None = None, code: str | None = None):
        code = code or ("hybrid" if hybrid_vars is not None else "lammps")
        return dem3d_silo.run(code, out=out, hybrid_vars=hybrid_vars, **self.size(n), **self.common)


def rate_uncertainty(dem, hyb) -> dict:
    """Each run's rate's standard error relative to its rate (its own fluctuation,
    hgtools.discharge.rate_standard_error) and that of the hybrid's rate error."""
    return dict(rate_se_dem=dem.rate_se / dem.rate, rate_se_hybrid=hyb.rate_se / hyb.rate,
                error_se=rate_ratio_se(hyb, dem))


def run_silo(silo: Silo, n: int, threads: int, work: Path, variants: tuple[tuple[tuple[str, float], ...], ...] = (),
             liggghts: bool = False) -> list[dict]:
    """The DEM and the hybrid at the fix's zones, then the hybrid at each of `variants` (pairs of a
    key of VARIANTS, the zone oracle's depth, the depth below the free surface only or the faces
    touched, and its value, lengths in grain diameters) against the same DEM run: one row each. `liggghts` (3D): pure LIGGGHTS from the
    same packing too, the DEM's noise floor (its rate against LAMMPS's)."""
    tag = "" if silo.dim == 2 else "3d_"
    silo.prepare(n, work)
    hybrids = []    # (deck variables, zone keys, run name) of the hybrid at the fix's zones and each variant
    for variant in (None, *variants):
        hvars, zones = dict(silo.hybrid_vars, htimeout=f"{REPLY_TIMEOUT:g}"), {key: None for key in VARIANTS}
        name = f"hybrid_{tag}{n}"
        for key, value in variant or ():
            hvars[VARIANTS[key][0]] = f"{value * D:.9g}" if VARIANTS[key][3] else variant_value(value)
            zones[key] = value
            name += f"_{VARIANTS[key][1]}{variant_value(value)}"
        hybrids.append((hvars, zones, name))
    timed = side_by_side([(name, partial(silo.run, n=n, out=work / name, hybrid_vars=hvars),
                           work / name / "discharge.dat")
                          for hvars, _, name in [(None, None, f"dem_{tag}{n}"), *hybrids]])
    (dem, dem_cpu, _), timed = timed[0], timed[1:]
    noise = None
    if liggghts:    # its rate only: not timed
        lig = silo.run(n, work / f"liggghts_{tag}{n}", code="liggghts")
        noise = lig.rate / dem.rate - 1
    rows = []
    for (hvars, zones, name), (hyb, hyb_cpu, running), variant in zip(hybrids, timed, (None, *variants)):
        row = dict(scene=silo.scene, grains=dem.grains, width_d=n, height_d=round(silo.depth * n), orifice_d=silo.orifice_d,
                   **zones, error=hyb.rate / dem.rate - 1, runout_error=None, discharge_s=silo.common["tdis"],
                   cores=silo.common["np_"],
                   lammps_ranks=silo.common["np_"], mpm_threads=threads, rate_dem=dem.rate, rate_hybrid=hyb.rate,
                   grain_rate_error=hyb.grain_rate / dem.grain_rate - 1, **rate_uncertainty(dem, hyb),
                   mass_per_grain_error=hyb.mass_per_grain / dem.mass_per_grain - 1, hcell=silo.hybrid_vars["hcell"],
                   interleaved=True,
                   **({} if noise is None else dict(noise_floor=noise, rate_liggghts=lig.rate,
                                                    noise_floor_se=rate_ratio_se(lig, dem))),
                   **speeds(dem, hyb, dem_cpu, hyb_cpu),
                   **cost_model(dem.loop_time, work / f"dem_{tag}{n}" / silo.log, work / name / silo.log, threads,
                                silo.dim, exchange_interval(hvars, work / name / silo.log), running))
        print(f"{silo.scene} W = {n} d{'' if variant is None else ', ' + variant_label(row)}: {dem.grains} grains, "
              f"speedup {row['speedup']:.2f}x (model {row['predicted_speedup']:.2f}x), rate {row['error']:+.1%}"
              f"{'' if noise is None else f' (LIGGGHTS {noise:+.1%})'}, continuum {row['continuum_share']:.0%}",
              flush=True)
        rows.append(row)
    return rows


COLLAPSE_TIMEOUT = 4 * 3600    # s, a column's preparation or one of its collapses at 200 d


def collapse_hybrids(n: int, hcell: str, zones: bool, touch: bool, depths: tuple = (),
                     everies: tuple = ()) -> list[tuple[str, dict, int | None, float | None, int | None]]:
    """The hybrids a collapse row set runs against its DEM: (run name, deck variables, touch, depth in
    grain diameters, exchange interval), None where the fix's or the deck's default holds. `zones`: the
    hybrid at the fix's zones; `touch`: the touched one (htouch 1) at the fix's depth; each of `depths`
    a touched one at that depth below the free surface; each of `everies` a touched one exchanging
    that often, at each of `depths` (at the fix's depth without them)."""
    out = [(f"hybrid_c{n}", {"hybrid": 2, "hcell": hcell}, None, None, None)] if zones else []
    touched = ([(None, None)] if touch else []) + [(x, None) for x in depths]
    touched += [(x, e) for x in (depths or (None,)) for e in everies]
    for depth, every in touched:
        hvars, name = {"hybrid": 2, "hcell": hcell, "htouch": 1}, f"hybrid_c{n}_touch1"
        if depth is not None:
            hvars["hdepth"], name = depth * D, f"{name}_depth{depth:g}"
        if every is not None:    # the deck runs the oracle every 10 exchanges
            hvars["hevery"], name = every, f"{name}_every{every}"
        out.append((name, hvars, 1, depth, every))
    return out


def run_collapse(n: int, np_: int, seed: int, hcell: str, threads: int, work: Path, touch: bool = False,
                 zones: bool = True, depths: tuple = (), everies: tuple = ()) -> list[dict]:
    """The 2D column collapse, a = 2, L0 = n d: DEM and the adaptive hybrids of collapse_hybrids() from
    the same cached column, to rest (the deck's criterion), in the same minutes; error = final surface
    RMS over H0 (grains and points). The depths below the free surface (deck variable hdepth; the fix's
    band) give the error against wall time as the grains' layer thins."""
    common = dict(aspect=ASPECT, width=n * D, d=D, np_=np_, seed=seed, timeout=COLLAPSE_TIMEOUT)
    prepare_column(ASPECT, n * D, D, np_, work / f"prep_c{n}", seed, timeout=common["timeout"])  # not timed
    hybrids = collapse_hybrids(n, hcell, zones, touch, depths, everies)
    timed = side_by_side([("dem", partial(collapse, out=work / f"dem_c{n}", **common), None),
                          *((name, partial(collapse, out=work / name, hybrid_vars=hvars, **common), None)
                            for name, hvars, *_ in hybrids)])
    (dem, dem_cpu, _), timed = timed[0], timed[1:]
    h0 = ASPECT * n * D
    rows = []
    for (name, _, touched, depth, every), (hyb, hyb_cpu, running) in zip(hybrids, timed):
        points = final_continuum(work / name)[0]["position"]
        surface = combine_surfaces(np.array(hyb.profile).T, points_surface(points, n * D / 20, 2 * D))
        row = dict(scene="collapse_2d", grains=dem.grains, width_d=n, height_d=int(ASPECT * n), orifice_d=None,
                   **{key: None for key in VARIANTS}, error=surface_error(surface, np.array(dem.profile).T, h0),
                   runout_error=hyb.runout / dem.runout - 1, steps_ratio=hyb.steps / dem.steps, cores=np_,
                   lammps_ranks=np_, mpm_threads=threads, runout_dem=dem.runout, runout_hybrid=hyb.runout,
                   dem_steps=dem.steps, hybrid_steps=hyb.steps,
                   hcell=hcell, interleaved=True, **speeds(dem, hyb, dem_cpu, hyb_cpu),
                   **cost_model(dem.loop_time, work / f"dem_c{n}" / "log.lammps", work / name / "log.lammps",
                                threads, every=every or EVERY, running=running))
        row["touch"], row["depth_d"], row["every"] = touched, depth, every
        print(f"collapse L0 = {n} d{'' if touched is None else ', touch 1'}"
              f"{'' if depth is None else f', depth {depth:g} d'}{'' if every is None else f', every {every}'}: "
              f"{dem.grains} grains, speedup "
              f"{row['speedup']:.2f}x (model {row['predicted_speedup']:.2f}x), surface {row['error']:.1%} of H0, "
              f"runout {row['runout_error']:+.1%}, steps x{row['steps_ratio']:.2f}, continuum "
              f"{row['continuum_share']:.0%}", flush=True)
        rows.append(row)
    return rows


def table(rows: list[dict]) -> list[str]:
    out = ["| scene | W or L0, H (d) | grains | LAMMPS ranks, MPM threads | continuum share (mean) | most points | "
           "DEM wall s | hybrid wall s | speedup (wall) | speedup (CPU time) | predicted | error | runout error | "
           "coupling s (MPM wait, rezones) | measured (UTC) |",
           "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    order = lambda r: (r["scene"], -r["cores"], r.get("pinned", False), r["width_d"],  # noqa: E731
                       *((r.get(k) is not None, isinstance(r.get(k), str), r.get(k) or 0) for k in VARIANTS))
    for r in sorted(rows, key=order):
        error = f"rate {r['error']:+.1%}" if r["scene"].startswith("silo") else f"surface {r['error']:.1%} of H0"
        if "discharge_s" in r:    # the discharge the rates are fitted over, from the opening
            error += f" over {r['discharge_s']:g} s"
        if "error_se" in r:    # the rate error's standard error, from the two runs' own fluctuation
            error += f" ± {r['error_se']:.1%}"
        if "steps_ratio" in r:    # a collapse: the hybrid's steps to rest over the DEM's (its cap if not at rest)
            error += f", steps x{r['steps_ratio']:.2f}"
        if "grain_rate_error" in r:    # the grains that left, counted (rows from 2026-11-26 on)
            error += f" (grains {r['grain_rate_error']:+.1%})"
        if "noise_floor" in r:    # pure LIGGGHTS from the same packing against LAMMPS
            error += f"; LIGGGHTS {r['noise_floor']:+.1%}" + (f" ± {r['noise_floor_se']:.1%}" if "noise_floor_se" in r
                                                              else "")
        runout = "" if r["runout_error"] is None else f"{r['runout_error']:+.1%}"
        cpu = f"{r['cpu_speedup']:.2f}x" if "cpu_speedup" in r else ""
        depth = f", {variant_label(r, unit='')}" if is_variant(r) else ""
        if r.get("seed", DEFAULT_SEED) != DEFAULT_SEED:
            depth += f", packing {r['seed']}"
        stops = " with stops" if r.get("interleaved") and "ledger_running_fraction" not in r else ""
        out.append(f"| {r['scene']} | {r['width_d']}, {r['height_d']}{depth} | {r['grains']} | {r['lammps_ranks']}, {r['mpm_threads']}{' (pinned)' if r.get('pinned') else ''} | {r['continuum_share']:.0%} | "
                   f"{r['points_max']} | {r['dem_wall_s']:.0f} | {r['hybrid_wall_s']:.0f} | {r['speedup']:.2f}x | "
                   f"{cpu} | {r['predicted_speedup']:.2f}x | {error} | {runout} | {r['coupling_s']:.1f} "
                   f"({r['mpm_wait_s']:.1f}, {r['rezone_s']:.1f}){stops} | {r.get('date', '').removesuffix(' UTC')}"
                   f"{', same minutes' if r.get('interleaved') else ''} |")
    return out


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, bx, cx, dx) = plt.subplots(1, 4, figsize=(21, 4.2))
    markers = {"silo_2d": "o", "silo_3d": "s", "collapse_2d": "^"}
    # a family: the scene at one aspect (a silo's fill height over its width), sizes along it
    aspect = lambda r: round(r["height_d"] / r["width_d"])  # noqa: E731
    families = sorted({(r["scene"], aspect(r)) for r in rows}, key=lambda f: (list(markers).index(f[0]), f[1]))
    for (scene, h_over_w), cores in product(families, sorted({r["cores"] for r in rows})):
        mine = sorted((r for r in rows if r["scene"] == scene and aspect(r) == h_over_w and r["cores"] == cores
                       and not is_variant(r)), key=lambda r: r["grains"])
        if not mine:
            continue
        g, marker = [r["grains"] for r in mine], markers[scene]
        name = scene if scene.startswith("collapse") or h_over_w == DEPTH else f"{scene}, H = {h_over_w} W"
        line, = ax.plot(g, [r["speedup"] for r in mine], marker + "-", label=f"{name}, {cores} core(s), measured")
        ax.plot(g, [r["predicted_speedup"] for r in mine], marker + "--", color=line.get_color(), alpha=0.6,
                label=f"{name}, {cores} core(s), cost model")
        for r in mine:
            note = f"rate {r['error']:+.1%}" if scene.startswith("silo") else f"surface {r['error']:.1%}"
            ax.annotate(note, (r["grains"], r["speedup"]), textcoords="offset points", xytext=(4, 6), fontsize=8)
            bx.plot(r["share_t"], r["share"], label=f"{scene}, {r['grains']} grains, {cores} core(s)")
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set(xscale="log", xlabel="grains", ylabel="DEM wall time / hybrid wall time")
    ax.legend(fontsize=8)
    bx.set(xlabel="t (s; silo: since the opening)", ylabel="continuum share of the material", ylim=(0, 1))
    bx.legend(fontsize=8)
    front(rows, cx)
    collapse_front(rows, dx)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def front(rows: list[dict], ax) -> None:
    """Error against wall time for each silo size run at several depths: the DEM at zero error,
    the hybrid at the fix's zones (star), at other depths (circles, joined) and at other depths
    below the free surface only (diamonds), on the same cores."""
    silo = [r for r in rows if r["scene"].startswith("silo") and not r.get("pinned")]
    for (scene, n, cores) in sorted({(r["scene"], r["width_d"], r["cores"]) for r in silo if is_variant(r)}):
        mine = [r for r in silo if r["scene"] == scene and r["width_d"] == n and r["cores"] == cores]
        n = f"{n} ({scene[-2:]})"
        at = lambda r: (r["hybrid_wall_s"], 100 * abs(r["error"]))  # noqa: E731
        default = [r for r in mine if not is_variant(r)]
        depth = sorted((r for r in mine if r.get("depth_d") is not None or not is_variant(r)),
                       key=lambda r: r["hybrid_wall_s"])
        line, = ax.plot(*zip(*map(at, depth)), "o-", label=f"hybrid, W = {n} d, {cores} core(s)")
        for marker, rule in (("D", lambda r: r.get("surface_depth_d") is not None and r.get("touch") is None),
                             ("^", lambda r: r.get("touch") is not None)):
            chosen = [r for r in mine if rule(r)]
            if chosen:
                ax.plot(*zip(*map(at, chosen)), marker, color=line.get_color())
        if default:
            ax.plot(*zip(*map(at, default)), "*", ms=12, color=line.get_color())
        ax.plot([mine[0]["dem_wall_s"]], [0.0], "s", color=line.get_color(), label=f"LAMMPS DEM, W = {n} d")
        for r in mine:
            ax.annotate(variant_label(r) if is_variant(r) else "default", at(r), textcoords="offset points",
                        xytext=(4, 4), fontsize=7)
    ax.set(xscale="log", yscale="symlog", xlabel="wall time, s", ylabel="|discharge rate error| (%)",
           title="circles: depth; diamonds: depth below the free surface only; triangles: floor touched")
    ax.title.set_fontsize(9)
    if ax.lines:    # (an invocation may have no silo at several depths)
        ax.legend(fontsize=8)


def collapse_label(r: dict) -> str:
    """A touched collapse hybrid's variants for the plot (all are touched), the fix's depth named."""
    label = variant_label(dict(r, touch=None))
    return label if r.get("depth_d") is not None else ", ".join(filter(None, ("depth 3 cells", label)))


def collapse_front(rows: list[dict], ax) -> None:
    """Error against wall time for the touched collapse hybrids of each invocation (one DEM run each:
    its wall time at zero error; one hybrid is a point against it): each hybrid's runout error
    (circles, joined in the order of their wall time) and final surface error over H0 (crosses)."""
    touched = [r for r in rows if r["scene"] == "collapse_2d" and not r.get("pinned") and r.get("touch") is not None]
    runs = {(r["width_d"], r["cores"], r.get("date", "")) for r in touched}
    for (n, cores, date) in sorted(runs):
        mine = sorted((r for r in touched if (r["width_d"], r["cores"], r.get("date", "")) == (n, cores, date)),
                      key=lambda r: r["hybrid_wall_s"])
        wall = [r["hybrid_wall_s"] for r in mine]
        line, = ax.plot(wall, [100 * abs(r["runout_error"]) for r in mine], "o-",
                        label=f"hybrid (touched), L0 = {n} d, {cores} core(s), {date.removesuffix(' UTC')}: runout")
        ax.plot(wall, [100 * r["error"] for r in mine], "x", color=line.get_color(), label="final surface / H0")
        ax.plot([mine[0]["dem_wall_s"]], [0.0], "s", color=line.get_color(), label=f"LAMMPS DEM, L0 = {n} d")
        for r in mine:
            ax.annotate(collapse_label(r), (r["hybrid_wall_s"], 100 * abs(r["runout_error"])),
                        textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set(xscale="log", xlabel="wall time, s", ylabel="error (%)",
           title="collapse: depth below the free surface, exchange interval")
    ax.title.set_fontsize(9)
    if ax.lines:
        ax.legend(fontsize=7, loc="center right")


def load(path: Path) -> tuple[dict, list[dict]]:
    """The saved JSON and all its rows: those at the fix's zones, then the other depths."""
    saved = json.loads(path.read_text())
    return saved, saved["rows"] + saved.get("depth_front", [])


def save(path: Path, rows: list[dict], **head) -> None:
    """The JSON: `rows`, one per scene, size and cores at the fix's zones (the issue's table), and
    `depth_front`, the silo's hybrid at other zone depths against the same DEM runs."""
    path.write_text(json.dumps(dict(**head, rows=[r for r in rows if not is_variant(r)],
                                    depth_front=[r for r in rows if is_variant(r)]), indent=1))


def write(rows: list[dict], command: str, stamp: str, out: Path) -> None:
    """The report (its notes kept) and the plot of these rows."""
    plot(rows, out.with_suffix(".png"))
    text = ["# Hybrid against pure LAMMPS DEM as the scene grows", "",
            (f"`{command}`, " if command else "") + f"{stamp} (each row's date in its last column; rows of other dates come from earlier invocations and code). DEM and hybrid of a row run side by side on the "
            "same LAMMPS ranks, the hybrid's MPM process (its threads) working while LAMMPS waits; a 2-core machine "
            "that may be shared (compare ratios). Rows marked 'same minutes' ran their DEM and hybrids interleaved, "
            "one at a time in quanta of 5 s (tools/hgtools/interleave.py), each timed by its quanta; earlier rows "
            "ran them one after the other. The coupling column is the fix's time ledger scaled to the time the "
            "hybrid ran; in rows marked 'with stops' (interleaved before 2026-12-04 20:30 UTC) it also counts the "
            "quanta of the other runs of the row, so it overstates the coupling by their share.", "",
            *table(rows), "", "![speedup against size](scale_speed.png)", ""]
    write_report(out, "\n".join(text))


def parse_list(text: str, kind=int, auto: bool = False) -> list:
    """Positive numbers (`kind`) from a comma list ('' = none), and 'auto' where `auto` allows it;
    ValueError names the value refused."""
    values = []
    for x in (t.strip() for t in text.split(",")):
        if not x:
            continue
        if auto and x == "auto":
            values.append(x)
            continue
        try:
            v = kind(x)
        except ValueError:
            raise ValueError(f"'{x}' is not {'a whole number' if kind is int else 'a number'}") from None
        if not v > 0:
            raise ValueError(f"'{x}' is not positive")
        values.append(v)
    return values


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--np", type=int, default=2, dest="np_", help="LAMMPS ranks, DEM and hybrid alike")
    ap.add_argument("--threads", type=int, default=2,
                    help="the MPM process's OpenMP threads (OMP_NUM_THREADS of the runs, and the cost model's)")
    ap.add_argument("--sizes", default="40,90,160", help="silo widths in grain diameters ('' = none)")
    ap.add_argument("--silo3d-sizes", default="12,18,26",
                    help="3D silo widths in grain diameters ('' = none): about 5k, 18k and 55k spheres")
    ap.add_argument("--silo3d-depth", type=float, default=DEPTH,
                    help="the 3D silo's fill height over its width (the zones' grains near the floor, the orifice "
                         "and the free surface fill a height that does not grow with the width)")
    ap.add_argument("--liggghts", action="store_true",
                    help="3D silo: also discharge each packing with pure LIGGGHTS (the DEM's noise floor)")
    ap.add_argument("--collapse-sizes", default="50,100,200", help="collapse widths L0 in grain diameters ('' = none)")
    ap.add_argument("--tdis", type=float, default=1.0,
                    help="the silo's discharge time after the opening, s (0.4 s, the default until 2026-11-27, hid a "
                         "hybrid band that drained after 0.5 s, and one run's rate has a standard error of about "
                         "2 %% over it)")
    ap.add_argument("--seed", type=int, default=DEFAULT_SEED,
                    help="the packing (random seed of the pour); each packing's rows are rows of their own")
    ap.add_argument("--hcell", default="0", help="the hybrid's cell, m, or 0 (the fix's, from the grains)")
    ap.add_argument("--depths", default="",
                    help="silo: also run the hybrid with these zone depths, grain diameters (e.g. '12,24'), "
                         "against the same DEM run: the error against wall time")
    ap.add_argument("--surface-depths", default="",
                    help="silo: also run the hybrid with these depths below the free surface only (fix keyword "
                         "surface_depth; the floor, walls and orifice keep the fix's depth), grain diameters")
    ap.add_argument("--every", default="",
                    help="silo: also run the hybrid exchanging every this many DEM steps (e.g. '20,40,auto'; the "
                         "deck's default is 10, its oracle every 10 exchanges; auto: the fix's every auto, the oracle "
                         "every 100 steps rounded up to a multiple), against the same DEM run")
    ap.add_argument("--touch-floor", action="store_true",
                    help="silo: also run the hybrid with the floor touched (htouch 2: the side walls and the floor, "
                         "the region over the orifice discrete), alone and with each --depths/--surface-depths")
    touch = ap.add_mutually_exclusive_group()
    touch.add_argument("--collapse-touch", action="store_true",
                    help="collapse: also run the hybrid whose continuum may touch the back wall and the floor "
                         "(htouch 1), against the same DEM run")
    touch.add_argument("--collapse-touch-only", action="store_true",
                    help="collapse: run the touched hybrid (htouch 1) and not the one at the fix's zones, whose rest "
                         "is fragile (2.65x the DEM's steps at 100 d on 2026-12-04): the DEM and one hybrid")
    touch.add_argument("--collapse-depths-only", action="store_true",
                    help="collapse: run only the touched hybrids of --collapse-depths and --collapse-every against "
                         "the DEM (neither the one at the fix's zones nor the touched one at the fix's depth)")
    ap.add_argument("--collapse-depths", default="",
                    help="collapse: also run the touched hybrid (htouch 1) with these depths below the free surface, "
                         "grain diameters (e.g. '12,9'; the fix's is 3 cells), against the same DEM run: the error "
                         "against wall time")
    ap.add_argument("--collapse-every", default="",
                    help="collapse: also run the touched hybrid exchanging every this many DEM steps (e.g. '20,40'; "
                         "the deck's 10, its oracle every 10 exchanges) at each of --collapse-depths (at the fix's "
                         "depth without them), against the same DEM run")
    ap.add_argument("--keep", action="store_true",
                    help="keep the rows of other (scene, size, cores) already in the JSON (each row has its date)")
    ap.add_argument("--pin", action="store_true",
                    help="pin the runs to the first --np cores (DEM and hybrid, MPM process included, share them): "
                         "equal cores even where a waiting process would poll on a free core")
    ap.add_argument("--prepare", action="store_true",
                    help="run nothing timed: only prepare (and cache) the settled silos of --sizes and --silo3d-sizes "
                         "and the columns of --collapse-sizes, "
                         "e.g. beside other work; a later invocation then times DEM and hybrid alone")
    ap.add_argument("--render", action="store_true",
                    help="run nothing: rewrite the report, the plot and the JSON's layout from the JSON "
                         "(after editing the notes)")
    ap.add_argument("--work", type=Path, default=REPO / "runs" / "scale_speed")
    ap.add_argument("--out", type=Path, default=RESULTS / "scale_speed.md")
    a = ap.parse_args()
    if not a.silo3d_depth > 0:
        ap.error(f"--silo3d-depth is the fill height over the width and must be > 0, not {a.silo3d_depth:g}")
    lists = {}    # every comma option, refused by name before anything runs
    for option, text, kind, auto, what in (
            ("--sizes", a.sizes, int, False, "silo widths in grain diameters"),
            ("--silo3d-sizes", a.silo3d_sizes, int, False, "3D silo widths in grain diameters"),
            ("--collapse-sizes", a.collapse_sizes, int, False, "collapse widths L0 in grain diameters"),
            ("--depths", a.depths, float, False, "zone depths in grain diameters"),
            ("--surface-depths", a.surface_depths, float, False, "depths below the free surface in grain diameters"),
            ("--every", a.every, int, True, "step counts or auto"),
            ("--collapse-depths", a.collapse_depths, float, False,
             "grain diameters (--collapse-every takes step counts)"),
            ("--collapse-every", a.collapse_every, int, False, "step counts (the collapse deck sets its oracle to 10 "
             "exchanges and has no every auto; --collapse-depths takes grain diameters)")):
        try:
            lists[option] = parse_list(text, kind, auto)
        except ValueError as e:
            ap.error(f"{option} takes {what}, comma-separated: {e}")
    collapse_depths, collapse_everies = tuple(lists["--collapse-depths"]), tuple(lists["--collapse-every"])
    if a.collapse_depths_only and not (a.collapse_depths or a.collapse_every):
        ap.error("--collapse-depths-only runs the hybrids at --collapse-depths or --collapse-every: give them, "
                 "e.g. --collapse-depths 9")
    if a.out.is_dir() or a.out.suffix != ".md":
        ap.error(f"--out is the report's file (its JSON and plot go beside it), e.g. {a.out / 'scale_speed.md'}, "
                 f"not {a.out}")
    path = a.out.with_suffix(".json")
    if a.render:
        if not path.exists():
            ap.error(f"--render rewrites the report from its JSON, and there is none at {path} (run the bench, or "
                     f"give --out the report beside its JSON)")
        saved, rows = load(path)
        save(path, rows, **{k: v for k, v in saved.items() if k not in ("rows", "depth_front")})
        write(rows, saved.get("command", ""), saved["date"], a.out)
        return 0
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    os.environ["OMP_NUM_THREADS"] = str(a.threads)    # the MPM process runs with what the model assumes
    if a.pin:    # inherited by every run this starts; Open MPI must not rebind its processes
        os.sched_setaffinity(0, set(range(a.np_)))
        os.environ["OMPI_MCA_hwloc_base_binding_policy"] = "none"
    sizes, sizes3d, collapse_sizes = (lists[o] for o in ("--sizes", "--silo3d-sizes", "--collapse-sizes"))
    variants = tuple(((key, x if x == "auto" else float(x)),)    # the fix's every auto
                     for key, option in (("depth_d", "--depths"), ("surface_depth_d", "--surface-depths"),
                                         ("every", "--every"))
                     for x in lists[option])
    if a.touch_floor:    # the floor touched, alone and with each of the other variants
        variants = variants + ((("touch", 2),),) + tuple((("touch", 2), *v) for v in variants)
    command = (f"bench/scale_speed.py --np {a.np_} --threads {a.threads} --sizes '{a.sizes}' --silo3d-sizes "
               f"'{a.silo3d_sizes}'{f' --silo3d-depth {a.silo3d_depth:g}' if a.silo3d_depth != DEPTH else ''}"
               f"{' --liggghts' if a.liggghts else ''} --collapse-sizes "
               f"'{a.collapse_sizes}' --tdis {a.tdis} --hcell {a.hcell}{f' --depths {a.depths}' if a.depths else ''}"
               f"{f' --surface-depths {a.surface_depths}' if a.surface_depths else ''}"
               f"{f' --every {a.every}' if a.every else ''}"
               f"{' --touch-floor' if a.touch_floor else ''}{' --collapse-touch' if a.collapse_touch else ''}{' --collapse-touch-only' if a.collapse_touch_only else ''}{' --collapse-depths-only' if a.collapse_depths_only else ''}{f' --collapse-depths {a.collapse_depths}' if a.collapse_depths else ''}{f' --collapse-every {a.collapse_every}' if a.collapse_every else ''}{' --pin' if a.pin else ''}{' --keep' if a.keep else ''}")
    saved_rows = load(path)[1] if a.keep and path.exists() else []
    saved_date = json.loads(path.read_text())["date"] if saved_rows else stamp
    rows: list[dict] = []

    def finish(new: list[dict]) -> None:
        """Adds a size's rows and writes the JSON and the report so far (a long invocation that
        stops keeps what it measured)."""
        for r in new:
            r["date"], r["pinned"], r["seed"] = stamp, a.pin, a.seed
        rows.extend(new)
        done = {row_key(r) for r in rows}
        old = [dict(r, date=r.get("date", saved_date)) for r in saved_rows if row_key(r) not in done]
        save(path, old + rows, date=stamp, np=a.np_, command=command)
        write(old + rows, command, stamp, a.out)

    silo2d, silo3d = Silo2d(a.np_, a.seed, a.tdis, a.hcell), Silo3d(a.np_, a.seed, a.tdis, a.hcell, a.silo3d_depth)
    if a.prepare:    # the packings only: their preparation is not timed, so it may share the machine
        for silo, ns in ((silo2d, sizes), (silo3d, sizes3d)):
            for n in ns:
                silo.prepare(n, a.work)
                print(f"{silo.scene} {n} d: settled silo cached", flush=True)
        for n in collapse_sizes:
            print(f"collapse_2d {n} d: settled column cached at "
                  f"{prepare_column(ASPECT, n * D, D, a.np_, a.work / f'prep_c{n}', a.seed, timeout=COLLAPSE_TIMEOUT)}", flush=True)
        return 0
    for n in sizes:
        finish(run_silo(silo2d, n, a.threads, a.work, variants))
    for n in sizes3d:
        finish(run_silo(silo3d, n, a.threads, a.work, variants, a.liggghts))
    for n in collapse_sizes:
        finish(run_collapse(n, a.np_, a.seed, a.hcell, a.threads, a.work, a.collapse_touch or a.collapse_touch_only,
                            zones=not (a.collapse_touch_only or a.collapse_depths_only), depths=collapse_depths,
                            everies=collapse_everies))
    return 0


if __name__ == "__main__":
    sys.exit(main())
