#!/usr/bin/env python3
"""Error-versus-run-time report of the planar granular column collapse: pure LAMMPS DEM (the
reference), the hybrid at several zone settings, pure MPM with each constitutive model, and
the noise floors of the reference itself, each with its wall time and its error.

    tools/collapse_report.py --out runs/report [--width 0.1] [--aspect 2] [--np 2]
                             [--runs dem,dem_seed,hybrid_fixed,...] [--liggghts]

Runs (all from the same settled column, except dem_seed):
  dem                 LAMMPS DEM, input_decks/column_collapse/dem_2d.lmp (the reference)
  dem_seed            the same scene from another packing (seed 2): the reference's own noise
  hybrid_fixed        fix hybrid/mpm with a fixed continuum block in the static wedge (hybrid 1)
  hybrid_adaptive     adaptive zones, the deck's default depth (hybrid 2)
  hybrid_adaptive_d2  adaptive zones, continuum from 2 deck cells (0.2 L0) below the surface
  hybrid_touch        adaptive zones, the continuum touching the back wall and the floor (htouch 1)
  hybrid_touch_<N>d   the same, continuum from N grain diameters below the free surface (e.g.
                      hybrid_touch_9d): the front of error against run time over the zones' depth
  mpm_drucker_prager  mpm_solver alone, Drucker-Prager
  mpm_mu_i            mpm_solver alone, mu(I)
With --liggghts, a reduced 3D slab collapse between side walls (tools/dem3d_collapse.py) runs in
LAMMPS, in LIGGGHTS and as the hybrid (fixed continuum block) on each of them as the DEM host: the
LAMMPS-LIGGGHTS difference is the reference's noise floor between codes (LIGGGHTS runs no 2D
scene); the hybrids' errors are against LAMMPS, and each hybrid's runout also against its own
host's pure DEM.

Errors against the reference: the final surface (RMS height difference from the wall to the
farther front, over H0), the runout (Lf - L0)/L0 (relative difference), the kinetic-energy
history (RMS difference of KE(t) over the reference's duration, over the reference's peak; grains
plus points for the hybrid), and whether the runout lies in the published range (docs/design.md
section 6). Speedup: the reference's wall time over the
run's, side by side in this job. The hybrids run on the deck's cells (L0/10) unless --hcell says
otherwise (0: the fix's cells from the grains, as bench/scale_speed.py runs them). Writes <out>/report.md, report.json, error_vs_time.png
(surface error against wall time, the noise floor as a band), profiles.png and
kinetic_energy.png (KE against time).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from column_collapse import (ColumnCollapse, combine_surfaces, normalised_runout, points_surface,
                             published_runout_range, surface_error)
from calibrate import describe_material
from dem_collapse import final_continuum, run as run_dem, run_from_settled
from hgtools import runner
from hgtools.logs import thermo_rows
from mpm_results import load_run

REPO = Path(__file__).resolve().parent.parent
SOLVER = runner.SOLVER
D = 0.002                 # grain diameter, m
ALL_RUNS = ["dem", "dem_seed", "hybrid_fixed", "hybrid_adaptive", "hybrid_adaptive_d2", "mpm_drucker_prager",
            "mpm_mu_i"]
LABELS = {
    "dem": "LAMMPS DEM (reference)", "dem_seed": "LAMMPS DEM, another packing (noise floor)",
    "hybrid_fixed": "hybrid, fixed continuum wedge", "hybrid_adaptive": "hybrid, adaptive zones",
    "hybrid_adaptive_d2": "hybrid, adaptive, depth 2 cells", "mpm_drucker_prager": "MPM Drucker-Prager",
    "mpm_mu_i": "MPM mu(I)", "hybrid_touch": "hybrid, adaptive, walls touched",
}
TOUCH_DEPTH = re.compile(r"hybrid_touch_(\d+(?:\.\d+)?)d")    # hybrid_touch_<N>d: depth N grain diameters
KNOWN_RUNS = ", ".join(ALL_RUNS + ["hybrid_touch", "hybrid_touch_<N>d"])    # for the errors


def known_run(name: str) -> bool:
    return name in ALL_RUNS or name == "hybrid_touch" or TOUCH_DEPTH.fullmatch(name) is not None


def label(name: str) -> str:
    depth = TOUCH_DEPTH.fullmatch(name)
    return f"hybrid, adaptive, walls touched, depth {depth.group(1)} d" if depth else LABELS[name]


@dataclass
class Outcome:
    name: str
    label: str
    runout: float
    surface: tuple                 # (x, height) arrays, m
    wall: float                    # s
    size: str
    steps: str
    height: float                  # final height / L0
    surface_error: float = float("nan")
    runout_error: float = float("nan")
    extra: dict = field(default_factory=dict)
    kinetic_energy: tuple = ((), ())   # (t since the release, KE per m of depth), s and J/m
    kinetic_error: float = float("nan")


def thermo_kinetic_energy(log: Path) -> tuple:
    """KE against time since the release: c_kef, plus f_couple[15] (the points') in a hybrid run."""
    rows = thermo_rows(log, require="v_xfront")    # the collapse stage's tables
    if not rows:
        raise RuntimeError(f"no thermo table of the collapse in {log}")
    t = np.array([r["Time"] for r in rows])
    return tuple(t - t[0]), tuple(r["c_kef"] + r.get("f_couple[15]", 0.0) for r in rows)


def frames_kinetic_energy(run) -> tuple:
    """KE against time of a pure MPM run's frames (mpm_results.Run)."""
    t, ke = [], []
    for i in range(len(run)):
        f = run.frame(i, fields=("mass", "velocity"))
        t.append(float(f["time"]))
        ke.append(0.5 * float(np.sum(f["mass"] * np.sum(f["velocity"] ** 2, axis=1))))
    return tuple(np.asarray(t) - t[0]), tuple(ke)


def kinetic_energy_error(run: tuple, ref: tuple) -> float:
    """RMS difference of two KE histories over the reference's times (a run that ended earlier
    keeps its last value), over the reference's peak."""
    tr, kr = (np.asarray(a) for a in ref)
    t, k = (np.asarray(a) for a in run)
    if t.size == 0 or tr.size == 0:    # an outcome saved before the histories were
        return float("nan")
    return float(np.sqrt(np.mean((np.interp(tr, t, k) - kr) ** 2)) / kr.max())


def dem_outcome(name: str, res, out: Path, points=None) -> Outcome:
    surface = np.array(res.profile).T
    size, height = f"{res.grains} grains", res.final_height
    if points is not None:    # the hybrid's continuum: the surface is the upper envelope of both
        surface = combine_surfaces(surface, points_surface(points, res.width / 20, 2 * D))
        size += f" + {len(points)} points"
        if len(points):       # (a continuum may have turned back into grains whole)
            height = max(height, float(points[:, 1].max()))
    return Outcome(name, label(name), res.runout, tuple(surface), res.wall_time, size, str(res.steps),
                   height / res.width, extra={"ms_per_step": 1e3 * res.loop_time / max(res.steps, 1)},
                   kinetic_energy=thermo_kinetic_energy(out / "log.lammps"))


def run_mpm(model: str, aspect: float, width: float, cell: float, out: Path, threads: int) -> Outcome:
    scene = ColumnCollapse(aspect=aspect, width=width, cell_size=cell, model=model, output_interval=0.05)
    work = out / f"mpm_{model}"
    path = scene.write(work)
    summary = work / "summary.json"
    done = runner.run_mpm(path, "--summary", summary, threads=threads)
    done.check("on the column", summary)
    wall = done.wall
    frames = load_run(work / "output")
    final = frames.frame(-1)
    figures = json.loads(summary.read_text())
    name = f"mpm_{model}"
    return Outcome(name, LABELS[name], normalised_runout(final["position"], width, cell),
                   tuple(points_surface(final["position"], cell / 2, 2 * D)), wall, f"{figures['points']} points",
                   f"{figures['steps']} (MPM)", float(np.max(final["position"][:, -1])) / width,
                   extra={"ms_per_step": 1e3 * wall / figures["steps"]}, kinetic_energy=frames_kinetic_energy(frames))


def hybrid_vars(name: str, aspect: float, width: float, hcell: float | None) -> dict:
    """The deck variables of a hybrid run (input_decks/column_collapse/dem_2d.lmp)."""
    # the deck's cell is L0/10: "depth 2 cells" is 0.2 L0
    # the fixed block (y < hy L0) stays below 0.6 H0, in the static wedge of low columns too
    named = {"hybrid_fixed": {"hy": min(0.7, 0.6 * aspect)}, "hybrid_adaptive": {"hybrid": 2},
             "hybrid_adaptive_d2": {"hybrid": 2, "hdepth": 0.2 * width}, "hybrid_touch": {"hybrid": 2, "htouch": 1}}
    depth = TOUCH_DEPTH.fullmatch(name)
    hvars = {"hybrid": 2, "htouch": 1, "hdepth": float(depth.group(1)) * D} if depth else dict(named[name])
    if hcell is not None:
        hvars["hcell"] = hcell
    return hvars


def run_one(name: str, aspect: float, width: float, cell: float, np_: int, out: Path,
            hcell: float | None = None) -> Outcome:
    common = dict(aspect=aspect, width=width, d=D, np_=np_)
    if name in ("dem", "dem_seed"):
        seed = {"dem": 12345, "dem_seed": 2}[name]    # the reference's packing, and another one
        res = run_from_settled(**common, out=out / name, seed=seed)    # timed alone, from the cached column
        return dem_outcome(name, res, out / name)
    if name.startswith("hybrid_"):
        res = run_dem(**common, out=out / name, hybrid_vars=hybrid_vars(name, aspect, width, hcell))
        return dem_outcome(name, res, out / name, final_continuum(out / name)[0]["position"])
    if name.startswith("mpm_"):
        return run_mpm(name[4:], aspect, width, cell, out, np_)
    raise ValueError(f"unknown run '{name}' (known: {KNOWN_RUNS})")


SLAB_ROWS = 5             # the 3D slab's thickness in floor rows of 1.2 d (6 d: 2.4 MPM cells of 2.5 d)


def slab_3d(aspect: float, np_: int, out: Path) -> dict:
    """The reduced 3D slab between frictional side walls (tools/dem3d_collapse.py, walls 1):
    LAMMPS (the 3D reference), LIGGGHTS (the noise floor between codes) and the hybrid with a
    fixed continuum block on each host (hybrid_3d.lmp in LAMMPS, hybrid_3d.liggghts in LIGGGHTS),
    from the same initial grains; each hybrid's host_error is against its own host's pure DEM. L0 = 15 d at a = 2,
    scaled as 1/sqrt(a) so that other aspect ratios hold about as many grains. Wall times are
    the collapse's alone (the codes' loop times after the gate opens)."""
    from dem3d_collapse import run as run3d
    width = round(0.03 * (2.0 / aspect) ** 0.5, 4)
    runs = {code: run3d(code=code, aspect=aspect, width=width, thickness_d=SLAB_ROWS, np_=np_,
                        out=out / f"slab_{code}", extra_vars={"walls": 1}, timeout=3600)
            for code in runner.CODES}
    ref = runs["lammps"]
    ref_surface = tuple(np.array(ref.profile).T)
    table = {}
    for code, res in runs.items():
        table[code] = dict(runout=res.runout, runout_error=(res.runout - ref.runout) / ref.runout,
                           surface_error=surface_error(tuple(np.array(res.profile).T), ref_surface, aspect * width),
                           collapse_wall=res.collapse_wall, collapse_steps=res.collapse_steps,
                           speedup=ref.collapse_wall / res.collapse_wall, grains=res.grains,
                           host_error=res.runout / runs[runner.host_dem(code)].runout - 1)
    return dict(aspect=aspect, width=width, thickness=ref.thickness, runs=table,
                difference=abs(ref.runout - runs["liggghts"].runout) / (0.5 * (ref.runout + runs["liggghts"].runout)))


def continuum_note() -> str:
    """Which continuum the runs used: the hybrids the material the 2D deck names by default (calibrated
    from its grains), pure MPM its scene's own constants."""
    return (f"Continuum of the hybrid runs: {describe_material('disks_2d')}; pure MPM runs with its scene's "
            "constants (Drucker-Prager 30 degrees, mu(I) of glass beads), which are not calibrated.")


def make_report(runs: list[Outcome], aspect: float, width: float, np_: int, codes: dict | None,
                command: str = "tools/collapse_report.py") -> str:
    ref = runs[0]
    lo, hi = published_runout_range(aspect)

    def law(r: float) -> str:
        return "yes" if lo <= r <= hi else f"no ({(r - np.clip(r, lo, hi)) / hi:+.0%})"

    lines = [f"# Column collapse, aspect ratio {aspect:g}, L0 = {width:g} m: error against run time", "",
             f"`{command}`, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {np_} LAMMPS "
             "rank(s) for every DEM and hybrid run (the hybrid adds one MPM process), MPM runs on as many threads. "
             f"Published runout (Lf - L0)/L0 for a = {aspect:g}: {lo:.2f} to {hi:.2f} (Lube et al. 2005; "
             "Lajeunesse et al. 2005). Surface error: RMS difference of the final surface height from the "
             "reference's, from the wall to the farther front, over H0. Speedup: the reference's wall time over "
             "the run's, side by side in this job. KE history error: RMS difference of the kinetic energy "
             "against time from the reference's, over its duration, over its peak. " + continuum_note(), "",
             "| run | (Lf - L0)/L0 | runout error | in published range | surface error vs DEM | KE history error | "
             "final height / L0 | size | steps | ms per step | wall s | speedup vs DEM |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in runs:
        err = "-" if r is ref else f"{r.surface_error:.1%}"
        rerr = "-" if r is ref else f"{r.runout_error:+.1%}"
        kerr = "-" if r is ref else f"{r.kinetic_error:.1%}"
        lines.append(f"| {r.label} | {r.runout:.2f} | {rerr} | {law(r.runout)} | {err} | {kerr} | {r.height:.2f} | {r.size} | "
                     f"{r.steps} | {r.extra.get('ms_per_step', float('nan')):.3f} | {r.wall:.1f} | "
                     f"{ref.wall / r.wall:.2f} |")
    if codes:
        labels = {"lammps": "LAMMPS DEM (3D reference)", "liggghts": "LIGGGHTS DEM (noise floor between codes)",
                  "hybrid": "hybrid, fixed continuum block (hybrid_3d.lmp)",
                  "hybrid_liggghts": "hybrid with LIGGGHTS as the DEM host (hybrid_3d.liggghts)"}
        lines += ["", f"## 3D slab between side walls, a = {codes['aspect']:g}, L0 = {codes['width']:g} m, "
                      f"W = {codes['thickness']:.3g} m", "",
                  "`tools/dem3d_collapse.py` with `walls 1` (frictional side walls: the continuum has no periodic "
                  "boundaries), the same initial grains in each code; wall time of the collapse alone. LAMMPS and "
                  f"LIGGGHTS runouts differ by {codes['difference']:.1%}.", "",
                  "| run | (Lf - L0)/L0 | runout error | runout error vs its host's DEM | surface error vs LAMMPS | "
                  "grains | steps | collapse wall s | speedup vs LAMMPS |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for code, r in codes["runs"].items():
            ref_row = code == "lammps"
            host = format(r["host_error"], "+.1%") if code.startswith("hybrid") and "host_error" in r else "-"
            lines.append(f"| {labels[code]} | {r['runout']:.2f} | {'-' if ref_row else format(r['runout_error'], '+.1%')} | "
                         f"{host} | {'-' if ref_row else format(r['surface_error'], '.1%')} | {r['grains']} | "
                         f"{r['collapse_steps']} | {r['collapse_wall']:.1f} | {r['speedup']:.2f} |")
    return "\n".join(lines) + "\n"


def finish(fig, ax, xlabel: str, ylabel: str, title: str, path: Path) -> None:
    import matplotlib.pyplot as plt
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plots(runs: list[Outcome], aspect: float, width: float, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref, lo_hi = runs[0], published_runout_range(aspect)
    fig, ax = plt.subplots(figsize=(6, 4))
    floor = [r.surface_error for r in runs if r.name == "dem_seed"]
    if floor:
        ax.axhspan(0, floor[0], color="grey", alpha=0.25, label="noise floor (DEM, another packing)")
    ax.axvline(ref.wall, color="k", ls=":", lw=1, label="DEM reference wall time")
    for i, r in enumerate(runs[1:]):
        ax.plot(r.wall, r.surface_error, "o", color=f"C{i}", label=r.label)
    ax.set_xscale("log")
    finish(fig, ax, "wall time, s", "final-surface error vs DEM (RMS / H0)",
           f"Column collapse a = {aspect:g}: error against run time", out / "error_vs_time.png")

    fig, ax = plt.subplots(figsize=(8, 3.2))
    for i, r in enumerate(runs):
        x, h = r.surface
        ax.plot(np.asarray(x) / width, np.asarray(h) / width, "k" if r is ref else f"C{i - 1}",
                lw=2 if r is ref else 1, label=r.label)
    ax.axvspan(1 + lo_hi[0], 1 + lo_hi[1], color="grey", alpha=0.2, label="published runout")
    finish(fig, ax, "x / L0", "surface height / L0", f"Column collapse, a = {aspect:g}: final surface",
           out / "profiles.png")

    fig, ax = plt.subplots(figsize=(6, 4))
    for i, r in enumerate(runs):
        t, ke = r.kinetic_energy
        ax.plot(t, ke, "k" if r is ref else f"C{i - 1}", lw=2 if r is ref else 1, label=r.label)
    finish(fig, ax, "time since the release, s", "kinetic energy, J per m of depth",
           f"Column collapse, a = {aspect:g}: kinetic energy", out / "kinetic_energy.png")


def run_report(out: Path, names: list[str], aspect: float = 2.0, width: float = 0.1, cell: float = 0.005,
               np_: int = 2, liggghts: bool = False, progress: bool = True,
               command: str = "tools/collapse_report.py", resume: bool = False,
               hcell: float | None = None) -> tuple[list[Outcome], dict | None]:
    """Runs the matrix (the reference "dem" first), writes the report and plots into out. Each
    run's outcome is saved as it ends (<out>/<run>.outcome.json); with resume, saved outcomes
    are reused, so an interrupted matrix goes on where it stopped (their wall times stay those
    of the run that made them)."""
    names = ["dem"] + [n for n in names if n != "dem"]
    unknown = [n for n in names if not known_run(n)]
    if unknown:
        raise ValueError(f"unknown run(s) {', '.join(unknown)} (known: {KNOWN_RUNS})")
    out = out.resolve()    # the drivers run the codes in other working directories
    out.mkdir(parents=True, exist_ok=True)
    runs, codes = [], None
    with tqdm(total=len(names) + int(liggghts), desc="collapse report", unit="run", disable=not progress) as bar:
        for name in names:
            bar.set_postfix_str(name)
            saved = out / f"{name}.outcome.json"
            if resume and saved.exists():
                runs.append(Outcome(**json.loads(saved.read_text())))
            else:
                runs.append(run_one(name, aspect, width, cell, np_, out, hcell))
                r = runs[-1]
                saved.write_text(json.dumps(dict(vars(r), surface=[np.asarray(a).tolist() for a in r.surface],
                                                 kinetic_energy=[np.asarray(a).tolist() for a in r.kinetic_energy])))
            bar.update()
        if liggghts:
            bar.set_postfix_str("3D slab: LAMMPS, LIGGGHTS, the hybrid on each")
            saved = out / "slab3d.json"
            codes = json.loads(saved.read_text()) if resume and saved.exists() else slab_3d(aspect, np_, out)
            saved.write_text(json.dumps(codes))
            bar.update()
    ref = runs[0]
    height0 = aspect * width
    for r in runs[1:]:
        r.surface_error = surface_error(r.surface, ref.surface, height0)
        r.runout_error = (r.runout - ref.runout) / ref.runout
        r.kinetic_error = kinetic_energy_error(r.kinetic_energy, ref.kinetic_energy)
    (out / "report.md").write_text(make_report(runs, aspect, width, np_, codes, command))
    (out / "report.json").write_text(json.dumps(
        {"aspect": aspect, "width": width, "np": np_, "codes": codes,
         "runs": [{"name": r.name, "label": r.label, "runout": r.runout, "runout_error": r.runout_error,
                   "surface_error": r.surface_error, "kinetic_error": r.kinetic_error, "wall": r.wall,
                   "size": r.size, "steps": r.steps, "height": r.height,
                   "surface": [np.asarray(a).tolist() for a in r.surface],
                   "kinetic_energy": [np.asarray(a).tolist() for a in r.kinetic_energy]} for r in runs]},
        indent=1))
    plots(runs, aspect, width, out)
    return runs, codes


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=REPO / "runs" / "report", help="output directory")
    p.add_argument("--aspect", type=float, default=2.0, help="column aspect ratio H0/L0")
    p.add_argument("--width", type=float, default=0.1, help="column width L0, m (0.05 for the reduced report)")
    p.add_argument("--cell", type=float, default=0.005, help="cell size of the pure MPM runs, m")
    p.add_argument("--np", dest="np_", type=int, default=os.cpu_count() or 1, help="LAMMPS ranks and MPM threads")
    p.add_argument("--runs", default=",".join(ALL_RUNS), help="comma-separated runs (see above)")
    p.add_argument("--liggghts", action="store_true",
                   help="add the 3D slab: LAMMPS, LIGGGHTS (the noise floor between codes) and the hybrid on each host")
    p.add_argument("--resume", action="store_true", help="reuse the outcomes an earlier call saved in --out")
    p.add_argument("--hcell", type=float, default=None,
                   help="the hybrids' MPM cell, m (0: the fix's, from the grains; default the deck's, L0/10)")
    args = p.parse_args(argv)
    if not SOLVER.exists():
        p.error(f"{SOLVER} is not built; run tools/setup.sh")
    try:
        runs, codes = run_report(args.out, [n.strip() for n in args.runs.split(",") if n.strip()], args.aspect,
                                 args.width, args.cell, args.np_, args.liggghts,
                                 command=" ".join(["tools/collapse_report.py"] + (argv or sys.argv[1:])),
                                 resume=args.resume, hcell=args.hcell)
    except ValueError as e:
        p.error(str(e))
    print((args.out / "report.md").read_text())
    print(f"collapse_report: {args.out / 'report.md'}, {args.out / 'error_vs_time.png'}, {args.out / 'profiles.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
