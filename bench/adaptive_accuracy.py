#!/usr/bin/env python3
"""Accuracy of the adaptive hybrid against pure LAMMPS DEM, and its independence of the
numerics (issue 14): each scene runs as pure DEM from the reference packing, as pure DEM from
another packing (the DEM's own noise floor) and as its adaptive hybrid twin (fix hybrid/mpm
with its defaults) for several exchange intervals and oracle intervals, side by side in one
invocation, from the same cached settled states.

Scenes and measures:
- collapse_2d, a = 2 and a = 0.5 (input_decks/column_collapse/dem_2d.lmp, `hybrid 2`): runout
  (Lf - L0)/L0, final surface (RMS over H0), kinetic-energy history (RMS over the DEM's peak),
  steps to rest over the DEM's (the deck's rest criterion);
- silo_2d (input_decks/silo/dem_2d.lmp + hybrid_2d.lmp): steady discharge rate, and the compaction (the
  material below 40 d over the DEM's, 0.2-0.8 s after the opening, from grain dumps and MPM frames every
  0.05 s); --silo deep (the default: W = 40 d, H = 120 d at the fix's grid from the grains) or shallow
  (W = 50 d, H = 75 d at the deck's 2.5 d cells);
- collapse_3d, silo_3d (tools/dem3d_collapse.py, dem3d_silo.py, code hybrid): runout and rate
  at the default numerics; their noise floor is LIGGGHTS against LAMMPS from the same grains.
Every hybrid row also gives the energy ledger's closure (largest residual over the largest
energy figure, tools/hgtools/logs.py) and the energy guard's margin (in parentheses: the largest
rise of what the coupling did, entries 23-28, above its lowest, over M |g| h; the fix stops a run
at its energy_guard, 5 % by default).

The 2D scenes run from one or more packings (--seeds): each packing's hybrids against the DEM
from the same packing, its noise floor the DEM from another packing against that DEM (the
reference packing's is OTHER_SEED's; every other packing's is the reference's), and the report
gives the mean over the packings of each numerics pair.

Usage: bench/adaptive_accuracy.py [--np 2] [--quick] [--scenes collapse_2d,silo_2d,...]
                                  [--exchanges 1,5,10,20] [--oracles 100,300,1000]
                                  [--seeds 12345,2] [--aspects 2,0.5] [--silo deep]
                                  [--hybrid-vars hfill=0.1,hsupport=0 [--hybrid-vars ...]]
--hybrid-vars sets deck variables of the 2D hybrid twins (a variant of the coupling against the
fix's defaults); given several times, each variant runs against the same DEM runs. Their rows name
them and are kept apart from the defaults' rows.
Writes bench/results/adaptive_accuracy.json (a list `rows`) and .md.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))
from collapse_report import kinetic_energy_error, thermo_kinetic_energy  # noqa: E402
from column_collapse import combine_surfaces, points_surface, surface_error  # noqa: E402
from dem_collapse import run as run_collapse, run_from_settled  # noqa: E402
from dem_silo import run_dem_silo  # noqa: E402
from hgtools.discharge import rate_ratio_se  # noqa: E402
from hgtools.logs import ledger_closure, thermo_rows  # noqa: E402
from hgtools.report import write_report  # noqa: E402
from hgtools.runner import RunFailed  # noqa: E402
from mpm_results import load_run  # noqa: E402
from scale_speed import silo_size  # noqa: E402
from silo_flow_field import dem_states, dem_timestep, hybrid_states, mass_below  # noqa: E402

D = 0.002
REFERENCE_SEED = 12345                          # the packing of the decks and the tests
OTHER_SEED = 2                                  # the reference packing's noise floor
EXCHANGES = (1, 5, 10, 20, "auto")              # at the oracle interval ORACLE_DEFAULT
ORACLES = (100, 300, 1000)                      # at the exchange interval EXCHANGE_DEFAULT
# the 2D decks' defaults with adaptive zones and untouched walls (every auto, the fix's default for
# them, since 2026-12-07: the continuum's stable substep, 36-46 DEM steps in these scenes; every 10
# before). The collapse deck keeps every 10 with htouch 1, but a row passes its interval explicitly:
# a variant with htouch=1 runs at the row's interval, as its label says
EXCHANGE_DEFAULT, ORACLE_DEFAULT = "auto", 100
NUMERICS_3D = {"collapse_3d": (10, 100), "silo_3d": (20, 200)}    # the 3D decks' own (exchange, oracle) steps


def exchange_interval(text: str):
    """An --exchanges value: a number of DEM steps, or auto (the fix's every auto)."""
    return text if text == "auto" else int(text)


def interval_order(every) -> tuple:
    """Rows sorted by exchange interval, auto after the numbers."""
    return (1, 0) if every == "auto" else (0, every or 0)


def numerics(exchanges, oracles) -> list[tuple[int, int]]:
    """Each exchange interval at the default oracle interval (the nearest multiple of it above, as
    the oracle runs right after an exchange; with auto the fix rounds it up), each oracle interval at the
    default exchange interval."""
    pairs = [(e, ORACLE_DEFAULT if e == "auto" else -(-ORACLE_DEFAULT // e) * e) for e in exchanges] + \
        [(EXCHANGE_DEFAULT, o) for o in oracles]
    return list(dict.fromkeys(pairs))


def ledger(log: Path) -> dict:
    """A hybrid run's ledger figures: its closure (largest residual over the largest energy figure) and
    the energy guard's margin (the fix's f_couple[36]: the largest rise of entries 23-28 above their
    lowest over M |g| h; None from a fix without the entry)."""
    rows = thermo_rows(log, require="f_couple[29]")
    shares = [r["f_couple[36]"] for r in rows if "f_couple[36]" in r]
    return dict(ledger_closure=ledger_closure(rows), guard_share=max(shares) if shares else None)


def overlap(log: Path) -> float | None:
    """The run's mean overlap of points and grains where they meet (the fix's f_couple[34]: the shared
    nodes' mass above a packed node's over their mass) over its thermo rows with points; None from a
    fix without the entry."""
    values = [r["f_couple[34]"] for r in thermo_rows(log, require="f_couple[34]") if r.get("f_couple[3]", 1) > 0]
    return float(np.mean(values)) if values else None


def fill_work(log: Path) -> float | None:
    """The fill pressure's work over the run (the fix's f_couple[35], a part of the continuum's own
    steps) over the energy the run released (the ledger's total, f_couple[19], first row less last):
    how much of what the flow spent the pressure gave back. None from a fix without the entry or a run
    that released nothing."""
    rows = thermo_rows(log, require="f_couple[35]")
    if not rows or not rows[0]["f_couple[19]"] - rows[-1]["f_couple[19]"] > 0:
        return None
    return rows[-1]["f_couple[35]"] / (rows[0]["f_couple[19]"] - rows[-1]["f_couple[19]"])


def floor_seed(seed: int) -> int:
    """The packing whose DEM is `seed`'s noise floor."""
    return OTHER_SEED if seed == REFERENCE_SEED else REFERENCE_SEED


def variant_name(variant: dict) -> str:
    """A run directory's suffix for the deck variables of a variant ('' for the fix's defaults)."""
    return "".join(f"_{k}{v}" for k, v in sorted(variant.items()))


def failed_run(key: dict, error: RunFailed) -> dict:
    """The row of one hybrid run that failed (its key's fields and why): the scene's other rows are
    kept, and the report lists it. `why` is the run's ERROR line when it printed one (the fix's
    energy guard, a crashed peer), else the failure's first lines."""
    text = str(error)
    errors = re.findall(r"^ERROR: .*$", text, re.MULTILINE)
    return dict(key, failed=(errors[0] if errors else text)[:2000])


def collapse_2d(work: Path, np_: int, aspect: float, width: float, pairs, seeds, variants=({},)) -> list[dict]:
    common = dict(aspect=aspect, width=width, d=D, np_=np_)
    h0 = aspect * width
    dems = {}

    def dem(s):    # the collapse alone, from the cached column, as the hybrid's; once per packing
        if s not in dems:
            out = work / f"dem_a{aspect:g}_s{s}"
            dems[s] = run_from_settled(**common, out=out, seed=s), thermo_kinetic_energy(out / "log.lammps")
        return dems[s]

    rows = []
    for variant, seed, every, oracle in ((v, s, e, o) for v in variants for s in seeds for e, o in pairs):
        (ref, ref_ke), (other, other_ke) = dem(seed), dem(floor_seed(seed))
        ref_surface = np.array(ref.profile).T
        floor = dict(surface=surface_error(np.array(other.profile).T, ref_surface, h0),
                     runout=other.runout / ref.runout - 1, ke=kinetic_energy_error(other_ke, ref_ke),
                     steps=other.steps / ref.steps)
        name = f"hybrid_a{aspect:g}_s{seed}_e{every}_o{oracle}{variant_name(variant)}"
        key = dict(scene="collapse_2d", grains=ref.grains, aspect=aspect, seed=seed, exchange_every=every,
                   oracle_every=oracle, **({"hybrid_vars": variant} if variant else {}))
        try:
            hyb = run_collapse(**common, out=work / name, seed=seed,
                               hybrid_vars={"hybrid": 2, "hevery": every, "hadapt": oracle, **variant})
        except RunFailed as e:
            rows.append(failed_run(key, e))
            print(f"collapse a = {aspect:g}{variant_label(key)}, seed {seed}, every {every}, oracle {oracle}: "
                  f"failed: {rows[-1]['failed'][:300]}", flush=True)
            continue
        points = load_run(work / name / "frames").frame(-1)["position"]
        surface = combine_surfaces(np.array(hyb.profile).T, points_surface(points, width / 20, 2 * D))
        rows.append(dict(
            key,
            runout_error=hyb.runout / ref.runout - 1, surface_error=surface_error(surface, ref_surface, h0),
            ke_error=kinetic_energy_error(thermo_kinetic_energy(work / name / "log.lammps"), ref_ke),
            rate_error=None, steps_ratio=hyb.steps / ref.steps, hybrid_at_rest=hyb.at_rest,
            noise_floor=floor["surface"], noise_floor_runout=floor["runout"], noise_floor_ke=floor["ke"],
            noise_floor_steps_ratio=floor["steps"], **ledger(work / name / "log.lammps"),
            overlap=overlap(work / name / "log.lammps"), fill_work=fill_work(work / name / "log.lammps"),
            dem_value=ref.runout, hybrid_value=hyb.runout, speedup=ref.wall_time / hyb.wall_time))
        print(f"collapse a = {aspect:g}{variant_label(rows[-1])}, seed {seed}, every {every}, oracle {oracle}: "
              f"runout {rows[-1]['runout_error']:+.1%}, "
              f"surface {rows[-1]['surface_error']:.1%}, steps x{rows[-1]['steps_ratio']:.2f}", flush=True)
    return rows


# The 2D silos (input_decks/silo/dem_2d.lmp + hybrid_2d.lmp), D = 10 d, 1 s of discharge. "deep" is
# bench/scale_speed.py's smallest (H = 3 W) at the fix's own grid from the grains (5.7 d cells, points of
# 8.5 disks: what a user of the fix gets); "shallow" the 50 d silo of the rows before 2026-12-02
# at the deck's 2.5 d cells (points of about 1.6 disks), whose 6 d cells would leave it no continuum.
SILOS = {
    "deep": dict(label="W 40 d, H 120 d, the fix's cells from the grains",
                 size=silo_size(40), hybrid={"hcell": 0}),
    "shallow": dict(label="W 50 d, H 75 d, the deck's 2.5 d cells",
                    size=dict(width=50 * D, height=75 * D, orifice=10 * D, d=D), hybrid={}),
}
SILO_DEFAULT, SILO_BEFORE = "deep", "shallow"    # rows without a `silo` key are SILO_BEFORE's


# The silo's compaction: its material (grains' carried mass and points) below COMPACTION_HEIGHT_D over the
# DEM's at the same time, averaged over COMPACTION_WINDOW after the opening, from the DEM's grain dumps and
# the hybrid's MPM frames every COMPACTION_EVERY s. The band's cells holding more than the packing's mass
# (points over grains) show as an excess that grows as the silo discharges (docs/design.md 5.3-5.4).
COMPACTION_HEIGHT_D, COMPACTION_WINDOW, COMPACTION_EVERY = 40, (0.2, 0.8), 0.05


def compaction(states, reference) -> float:
    """The mean over COMPACTION_WINDOW of states' mass below COMPACTION_HEIGHT_D over reference's (at the
    same time, interpolated), less 1."""
    def below(st):
        b = mass_below(st, (COMPACTION_HEIGHT_D,))
        return np.array(b["t"]), np.array([m[0] for m in b["mass"]])
    t, m = below(states)
    t_ref, m_ref = below(reference)
    inside = (t >= COMPACTION_WINDOW[0] - 1e-9) & (t <= COMPACTION_WINDOW[1] + 1e-9)
    return float(np.mean(m[inside] / np.interp(t[inside], t_ref, m_ref)) - 1) if inside.any() else float("nan")


def frame_every(dem_out: Path, every) -> int:
    """Exchanges between the hybrid's MPM frames for one every COMPACTION_EVERY s, at the DEM's step.
    With every auto the interval is known only once the run starts; taking the oracle's steps for it
    (more than the fix chooses in these scenes) gives frames at least that often."""
    steps = ORACLE_DEFAULT if every == "auto" else every
    return max(1, round(COMPACTION_EVERY / (dem_timestep(dem_out) * steps)))


def silo_2d(work: Path, np_: int, quick: bool, pairs, seeds, silo: str = SILO_DEFAULT, variants=({},)) -> list[dict]:
    size = dict(width=0.06, height=0.08, orifice=0.016, d=D, tdis=0.8, fstop=0.6) if quick else \
        dict(SILOS[silo]["size"], tdis=1.0, fstop=0.9)
    hybrid = {} if quick else SILOS[silo]["hybrid"]
    common = dict(np_=np_, extra_vars={"mu": 0.5, "e": 0.5}, **size)
    dems = {}

    def dem(s):    # once per packing, with its grains dumped for the compaction
        if s not in dems:
            out = work / f"silo_{silo}_dem_s{s}"
            res = run_dem_silo(out=out, seed=s, **dict(common, extra_vars={**common["extra_vars"], "tdump": COMPACTION_EVERY}))
            dems[s] = res, out, dem_states(out)
        return dems[s]

    rows = []
    for variant, seed, every, oracle in ((v, s, e, o) for v in variants for s in seeds for e, o in pairs):
        (ref, ref_out, ref_states), (other, _, other_states) = dem(seed), dem(floor_seed(seed))
        name = f"silo_{silo}_s{seed}_e{every}_o{oracle}{variant_name(variant)}"
        frames = {"houtev": frame_every(ref_out, every), "hout": work / name / "frames"}
        key = dict(scene="silo_2d", silo=None if quick else silo, grains=ref.grains, aspect=None, seed=seed,
                   exchange_every=every, oracle_every=oracle, **({"hybrid_vars": variant} if variant else {}))
        try:
            hyb = run_dem_silo(out=work / name, seed=seed,
                               hybrid_vars={"hevery": every, "hadapt": oracle, **hybrid, **variant, **frames}, **common)
        except RunFailed as e:
            rows.append(failed_run(key, e))
            print(f"silo ({'reduced' if quick else silo}){variant_label(key)}, seed {seed}, every {every}, "
                  f"oracle {oracle}: failed: {rows[-1]['failed'][:300]}", flush=True)
            continue
        hyb_states, _ = hybrid_states(work / name)
        rows.append(dict(
            key,
            runout_error=None, surface_error=None, ke_error=None, rate_error=hyb.rate / ref.rate - 1,
            steps_ratio=None, noise_floor=other.rate / ref.rate - 1, rate_error_se=rate_ratio_se(hyb, ref),
            noise_floor_se=rate_ratio_se(other, ref), **ledger(work / name / "log.lammps"),
            dem_value=ref.rate, hybrid_value=hyb.rate, speedup=ref.wall_time / hyb.wall_time,
            compaction=compaction(hyb_states, ref_states), noise_floor_compaction=compaction(other_states, ref_states),
            overlap=overlap(work / name / "log.lammps"), fill_work=fill_work(work / name / "log.lammps")))
        print(f"silo ({'reduced' if quick else silo}){variant_label(rows[-1])}, seed {seed}, every {every}, "
              f"oracle {oracle}: rate {rows[-1]['rate_error']:+.1%}, compaction {rows[-1]['compaction']:+.1%}", flush=True)
    return rows


def collapse_3d(work: Path, np_: int) -> list[dict]:
    """The reduced 3D slab between side walls (as tools/collapse_report.py's 3D section), the
    hybrid with adaptive zones; its noise floor is LIGGGHTS against LAMMPS from the same grains."""
    from collapse_report import SLAB_ROWS
    from dem3d_collapse import run
    common = dict(aspect=2.0, width=0.03, thickness_d=SLAB_ROWS, np_=np_, timeout=3600)
    ref = run("lammps", out=work / "c3_lammps", extra_vars={"walls": 1}, **common)
    other = run("liggghts", out=work / "c3_liggghts", extra_vars={"walls": 1}, **common)
    # adaptive zones with the depth of the 2D collapse's (3 cells; the deck's default hdepth is
    # one cell, for the fixed block, and adaptive zones need depth > band)
    hyb = run("hybrid", out=work / "c3_hybrid", extra_vars={"walls": 1, "hmode": 2, "hdepth": 0.015}, **common)
    return [dict(scene="collapse_3d", grains=ref.grains, aspect=ref.aspect, exchange_every=NUMERICS_3D["collapse_3d"][0],
                 oracle_every=NUMERICS_3D["collapse_3d"][1], runout_error=hyb.runout / ref.runout - 1, surface_error=None,
                 ke_error=None, rate_error=None, steps_ratio=hyb.collapse_steps / ref.collapse_steps,
                 noise_floor=other.runout / ref.runout - 1, noise_floor_is="LIGGGHTS",
                 **ledger(work / "c3_hybrid" / "log.txt"), dem_value=ref.runout,
                 hybrid_value=hyb.runout, speedup=ref.collapse_wall / hyb.collapse_wall)]


def silo_3d(work: Path, np_: int) -> list[dict]:
    """The 3D silo at its driver's size; noise floor: LIGGGHTS against LAMMPS from the same grains."""
    from dem3d_silo import run
    ref = run("lammps", np_=np_, out=work / "s3_lammps")
    other = run("liggghts", np_=np_, out=work / "s3_liggghts")
    hyb = run("hybrid", np_=np_, out=work / "s3_hybrid")
    return [dict(scene="silo_3d", grains=ref.grains, aspect=None, exchange_every=NUMERICS_3D["silo_3d"][0],
                 oracle_every=NUMERICS_3D["silo_3d"][1], runout_error=None, surface_error=None, ke_error=None,
                 rate_error=hyb.rate / ref.rate - 1, steps_ratio=None, noise_floor=other.rate / ref.rate - 1,
                 rate_error_se=rate_ratio_se(hyb, ref), noise_floor_se=rate_ratio_se(other, ref),
                 noise_floor_is="LIGGGHTS", **ledger(work / "s3_hybrid" / "log.txt"),
                 dem_value=ref.rate, hybrid_value=hyb.rate, speedup=ref.wall_time / hyb.wall_time)]


def pct(v, se=None) -> str:
    """A relative error, with its standard error (silo rates: the runs' own fluctuation) when known."""
    return "" if v is None else f"{100 * v:+.1f} %" + ("" if se is None else f" ± {100 * se:.1f} %")


def table(rows: list[dict]) -> list[str]:
    lines = ["| scene | grains | a | packing | exchange every | oracle every | runout | surface / H0 | KE history | "
             "rate | compaction (floor) | steps to rest / DEM's | noise floor (another packing) | ledger closure (guard) | "
             "speed vs DEM |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        floor = pct(r["noise_floor"], r.get("noise_floor_se")) + (f" ({r['noise_floor_is']})" if "noise_floor_is" in r else "") \
            if r["scene"] != "collapse_2d" else (
            f"surface {100 * r['noise_floor']:.1f} %, runout {pct(r['noise_floor_runout'])}, "
            f"KE {100 * r['noise_floor_ke']:.1f} %, steps x{r['noise_floor_steps_ratio']:.2f}")
        lines.append(" | ".join([
            f"| {scene_name(r)}", str(r["grains"]), "" if r["aspect"] is None else f"{r['aspect']:g}",
            str(r.get("seed", "")), str(r["exchange_every"]), str(r["oracle_every"]), pct(r["runout_error"]),
            "" if r["surface_error"] is None else f"{100 * r['surface_error']:.1f} %",
            "" if r["ke_error"] is None else f"{100 * r['ke_error']:.1f} %", pct(r["rate_error"], r.get("rate_error_se")),
            "" if r.get("compaction") is None else f"{pct(r['compaction'])} ({pct(r['noise_floor_compaction'])})",
            "" if r["steps_ratio"] is None else f"{r['steps_ratio']:.2f}", floor,
            f"{r['ledger_closure']:.1e}" + ("" if r.get("guard_share") is None else f" ({100 * r['guard_share']:.2f} %)"),
            f"{r['speedup']:.2f}x |"]))
    return lines


def mean_table(rows: list[dict]) -> list[str]:
    """Each 2D numerics pair's errors on the mean over the packings measured, where there are several,
    with the mean's standard error over the packings and the DEM's own spread over them (the runout's or
    the rate's standard deviation over the packings' DEM runs, relative to their mean): a hybrid mean
    within that spread is as close to the DEM as another set of packings would be."""
    groups = {}
    for r in rows:
        if r["scene"] in ("collapse_2d", "silo_2d") and "seed" in r:
            groups.setdefault((scene_name(r), r["aspect"], r["exchange_every"], r["oracle_every"]), []).append(r)
    groups = {k: g for k, g in groups.items() if len({r["seed"] for r in g}) > 1}
    if not groups:
        return []
    lines = ["", "Means over the packings (each packing's hybrid against its own DEM; ± the mean's standard "
                 "error over the packings; the DEM's spread: its runout's or rate's standard deviation over the "
                 "packings over their mean; overlap: the fix's f_couple[34] over the run, shared nodes' mass "
                 "above the packing's; fill work: the fill pressure's, f_couple[35], over the energy the run released):", "",
             "| scene | a | packings | exchange every | oracle every | runout | surface / H0 | rate | compaction | "
             "steps to rest / DEM's | overlap | fill work | DEM's spread | noise floors |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]

    def values(g, key):
        return [r[key] for r in g if r.get(key) is not None]

    def mean(g, key, scale=100.0, fmt="{:+.1f} %", se=False):
        v = values(g, key)
        if not v:
            return ""
        text = fmt.format(scale * float(np.mean(v)))
        return text + (f" ± {scale * float(np.std(v, ddof=1)) / np.sqrt(len(v)):.1f} %" if se and len(v) > 1 else "")

    for (scene, aspect, every, oracle), g in groups.items():
        floors = ", ".join(pct(r["noise_floor_runout"] if r["scene"] == "collapse_2d" else r["noise_floor"]) for r in g)
        dem = np.array(values(g, "dem_value"))
        spread = f"{100 * float(np.std(dem, ddof=1) / np.mean(dem)):.1f} %" if len(dem) > 1 else ""
        lines.append(" | ".join([
            f"| {scene}", "" if aspect is None else f"{aspect:g}", ", ".join(str(r["seed"]) for r in g), str(every),
            str(oracle), mean(g, "runout_error", se=True), mean(g, "surface_error", fmt="{:.1f} %"),
            mean(g, "rate_error", se=True), mean(g, "compaction"), mean(g, "steps_ratio", scale=1.0, fmt="{:.2f}"),
            mean(g, "overlap", fmt="{:.1f} %"), mean(g, "fill_work", fmt="{:.1f} %"), spread, floors + " |"]))
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--np", type=int, default=2, dest="np_", help="LAMMPS ranks, for all runs")
    ap.add_argument("--quick", action="store_true", help="reduced sizes, default numerics only")
    ap.add_argument("--scenes", default="collapse_2d,silo_2d,collapse_3d,silo_3d",
                    help="comma-separated: collapse_2d, silo_2d, collapse_3d, silo_3d")
    ap.add_argument("--exchanges", default=",".join(map(str, EXCHANGES)),
                    help="exchange intervals to run, steps or auto (at the default oracle interval; '' for none)")
    ap.add_argument("--oracles", default=",".join(map(str, ORACLES)),
                    help="oracle intervals to run (at the default exchange interval; '' for none)")
    ap.add_argument("--seeds", default=str(REFERENCE_SEED),
                    help=f"packings of the 2D scenes, comma-separated (the reference {REFERENCE_SEED} first)")
    ap.add_argument("--aspects", default="2,0.5", help="aspect ratios of collapse_2d (2 and/or 0.5)")
    ap.add_argument("--silo", choices=sorted(SILOS), default=SILO_DEFAULT,
                    help="silo_2d's silo: " + "; ".join(f"{k}: {v['label']}" for k, v in SILOS.items()))
    ap.add_argument("--hybrid-vars", action="append", type=hybrid_vars_option, default=[],
                    help="deck variables of the 2D hybrid twins, NAME=VALUE,... (e.g. hfill=0.1): a variant of "
                         "the coupling, reported apart from the fix's defaults; repeat for several variants "
                         "(an empty value: the defaults), all against the same DEM runs")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "adaptive_accuracy.md")
    ap.add_argument("--keep", action="store_true",
                    help="keep the rows of the JSON that this run does not measure again (each row has its "
                         "date and command)")
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    scenes = args.scenes.split(",")
    unknown = set(scenes) - set(SCENE_ORDER)
    if unknown:
        ap.error(f"unknown scene(s) {', '.join(sorted(unknown))}")
    pairs = [(EXCHANGE_DEFAULT, ORACLE_DEFAULT)] if args.quick else \
        numerics([exchange_interval(v) for v in args.exchanges.split(",") if v], [int(v) for v in args.oracles.split(",") if v])
    width = {2.0: 0.05 if args.quick else 0.1, 0.5: 0.1 if args.quick else 0.2}
    seeds = [int(v) for v in args.seeds.split(",")]
    aspects = [float(v) for v in args.aspects.split(",")]
    if set(aspects) - set(width):
        ap.error(f"--aspects takes 2 and/or 0.5 (got {args.aspects})")
    path = args.out.with_suffix(".json")
    kept = []
    if args.keep and path.exists():    # earlier rows, dated as they were measured
        saved = json.loads(path.read_text())
        # files written before rows carried their command name it only in the report's first line
        old_report = args.out.read_text().split("`") if args.out.exists() else []
        before = old_report[1] if len(old_report) > 2 else ""
        kept = [dict(r, date=r.get("date", saved["date"]), command=r.get("command", before)) for r in saved["rows"]]
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    rows = []
    with tempfile.TemporaryDirectory(prefix="adaptive_accuracy_") as tmp:
        work = Path(tmp)
        variants = args.hybrid_vars or [{}]
        jobs = [(f"collapse_2d a = {a:g}", lambda a=a: collapse_2d(work, args.np_, a, width[a], pairs, seeds, variants))
                for a in aspects if "collapse_2d" in scenes]
        jobs += [(name, job) for name, job in (("silo_2d", lambda: silo_2d(work, args.np_, args.quick, pairs, seeds, args.silo, variants)),
                                               ("collapse_3d", lambda: collapse_3d(work, args.np_)),
                                               ("silo_3d", lambda: silo_3d(work, args.np_))) if name in scenes]
        for name, job in jobs:    # a scene that fails is reported; the others' figures are kept
            try:
                rows += [dict(r, date=stamp, command=command(args)) for r in job()]
            except Exception as e:    # noqa: BLE001 - the bench goes on, the file says what failed
                print(f"{name} failed: {e}", flush=True)
                rows.append(dict(scene=name, failed=str(e)[:2000], date=stamp, command=command(args)))
            write(args, merge(kept, rows))
    write(args, merge(kept, rows))
    print(f"wrote {args.out}")
    return 0


def silo_of(r: dict) -> str | None:
    """A silo_2d row's silo (SILOS; a quick run's reduced one: None), other scenes' None."""
    return r.get("silo", SILO_BEFORE) if r["scene"] == "silo_2d" else None


def hybrid_vars_option(text: str) -> dict:
    """--hybrid-vars: 'NAME=VALUE,...' as a dict of deck variables (numbers where they read as one)."""
    out = {}
    for item in filter(None, text.split(",")):
        name, sep, value = item.partition("=")
        if not sep or not name.startswith("h") or not value:
            raise argparse.ArgumentTypeError(f"--hybrid-vars takes NAME=VALUE items of the hybrid twin's deck "
                                             f"variables (h...), not '{item}'")
        try:
            out[name] = int(value) if value.lstrip("-").isdigit() else float(value)
        except ValueError:
            out[name] = value
    return out


def variant_label(r: dict) -> str:
    """' (hfill 0.1, ...)' for a row of a variant, '' for the fix's defaults."""
    v = r.get("hybrid_vars") or {}
    return f" ({', '.join(f'{k} {v[k]:g}' if isinstance(v[k], (int, float)) else f'{k} {v[k]}' for k in sorted(v))})" if v else ""


def scene_name(r: dict) -> str:
    return (r["scene"] if silo_of(r) is None else f"{r['scene']} {silo_of(r)}") + variant_label(r)


def row_key(r: dict) -> tuple:
    """What a row measures: its scene (a failed one: the whole scene) and silo, aspect, packing and numerics."""
    return (r["scene"], silo_of(r), r.get("aspect"), r.get("seed", REFERENCE_SEED), r.get("exchange_every"),
            r.get("oracle_every"), variant_label(r))


def scene_failed(r: dict) -> bool:
    """A row that says its whole scene failed (a DEM reference, a 3D scene), not one run of it."""
    return "failed" in r and "exchange_every" not in r


def merge(kept: list[dict], rows: list[dict]) -> list[dict]:
    """The new rows, and the kept ones that none of them measures again (a kept failure of a whole
    scene: none of its scene; a kept failure of one run: as any row, by its run)."""
    new, scenes = {row_key(r) for r in rows}, {r["scene"].split(" ")[0] for r in rows}
    return [r for r in kept if row_key(r) not in new and not (scene_failed(r) and r["scene"].split(" ")[0] in scenes)] + rows


def command(args) -> str:
    return (f"bench/adaptive_accuracy.py{' --quick' if args.quick else ''} --np {args.np_} --scenes {args.scenes}"
            f"{'' if args.quick else f' --exchanges {args.exchanges} --oracles {args.oracles}'}"
            f" --seeds {args.seeds}{f' --aspects {args.aspects}' if 'collapse_2d' in args.scenes else ''}"
            f"{f' --silo {args.silo}' if 'silo_2d' in args.scenes and not args.quick else ''}"
            + "".join(f" --hybrid-vars '{','.join(f'{k}={v}' for k, v in variant.items())}'" for variant in args.hybrid_vars))


SCENE_ORDER = ("collapse_2d", "silo_2d", "collapse_3d", "silo_3d")


def write(args, rows: list[dict]) -> None:
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    order = {name: k for k, name in enumerate(SCENE_ORDER)}
    rows = sorted(rows, key=lambda r: (order.get(r["scene"].split(" ")[0], len(order)), silo_of(r) or "", -(r.get("aspect") or 0),
                                       interval_order(r.get("exchange_every")), r.get("oracle_every") or 0,
                                       r.get("seed") != REFERENCE_SEED, r.get("seed") or 0))
    runs = sorted({(r.get("date", stamp), r.get("command", command(args))) for r in rows})
    lines = ["# Adaptive hybrid against pure LAMMPS DEM: accuracy and independence of the numerics", "",
             "; ".join(f"`{c}`, {d}" for d, c in runs) + f" (each row's date in the JSON); "
             f"{args.np_} LAMMPS rank(s) for DEM and hybrid alike, plus one MPM process for the hybrid, "
             "on a 2-core machine, side by side in one run. Errors are the hybrid's against the DEM from the same "
             "packing; the noise floor is the DEM from another packing against it (same measure). The hybrid "
             "runs with the fix's defaults of its row's date (adaptive zones; the grain update pic 0 before "
             "2026-11-29, pic regime with its share per exchange on 2026-11-29, at the agreement's rate since "
             "2026-12-01, only where the material is also still since 2026-12-07) and the decks' material, a "
             "variant's rows (deck variables in parentheses after the scene) with those set; rows with a packing come from each packing's own DEM. The silos' compaction: their "
             "material below 40 d over the DEM's, 0.2-0.8 s after the opening (in parentheses the other packing's "
             "DEM's). The 2D silos: "
             + "; ".join(f"{k}, {v['label']}" for k, v in SILOS.items()) + ".", ""]
    lines += table([r for r in rows if "failed" not in r])
    lines += mean_table([r for r in rows if "failed" not in r])
    lines += [f"\n{r['scene']} failed: {r['failed'][:300]}" for r in rows if scene_failed(r)]
    lines += [f"\n{scene_name(r)}, packing {r.get('seed', REFERENCE_SEED)}, every {r['exchange_every']}, oracle every "
              f"{r['oracle_every']}: the hybrid failed (not in the means): {r['failed'][:600]}" for r in rows if "failed" in r and not scene_failed(r)]
    lines += ["", "Targets (issue 14): runout within 5 %, final surface <= 3 % of H0, KE history <= 5 %, steps to "
              "rest <= 1.2x the DEM's; silo rate within 2 %; 3D within the LAMMPS-LIGGGHTS spread; the same for "
              "every exchange and oracle interval."]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_report(args.out, "\n".join(lines))    # the notes below the marker are kept
    args.out.with_suffix(".json").write_text(json.dumps(dict(date=stamp, np=args.np_, rows=rows), indent=1))


if __name__ == "__main__":
    sys.exit(main())
