#!/usr/bin/env python3
"""The deep 2D silo's error against run time, one size in one invocation: pure LAMMPS DEM (the
reference), the DEM's noise floor (the same silo from another packing), the hybrid at the fix's
zones and at other zone depths, and pure MPM with each constitutive model at cells of several
grain sizes, each with its discharge rate's error against the DEM and its wall time, on one plot.
A hybrid pays off where its point lies left of the DEM (faster) and below every pure MPM run (more
accurate), ideally within the noise floor.

How it times them: the DEM and the hybrids run interleaved in the same minutes
(bench/scale_speed.py's run_silo, tools/hgtools/interleave.py), each timed by its own quanta; the
pure MPM runs follow one after the other on the same cores (--threads OpenMP threads), timed by
their wall time (minutes later: a drifting machine moves their ratio to the DEM). The other
packing's DEM is not timed: it gives the noise floor, the rate difference between two packings
(with its standard error from the two runs' own fluctuation, hgtools.discharge.rate_ratio_se).

Usage: bench/silo_front.py [--width-d 40] [--depths 12,24] [--cells 2,1] [--models drucker_prager,mu_i]
                           [--noise-seed 2] [--np 2] [--threads 2] [--tdis 1.0]
Writes bench/results/silo_front_<W>.{json,md,png}, W the width in d (the notes below the marker kept).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from datetime import datetime, timezone
from pathlib import Path
from types import SimpleNamespace

REPO = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(REPO / "tools"), str(REPO / "bench")]
from hgtools.discharge import rate_ratio_se  # noqa: E402
from hgtools.report import write_report  # noqa: E402
from mpm_silo import MpmSilo, run as run_mpm_silo  # noqa: E402
from scale_speed import D, DEPTH, ORIFICE, RESULTS, Silo2d, run_silo, silo_size  # noqa: E402

MPM_LABELS = {"drucker_prager": "Drucker-Prager", "mu_i": "mu(I)"}


def verdicts(rows: list[dict]) -> list[dict]:
    """For each hybrid row: is it left of the DEM (less wall time), below pure MPM (a smaller |rate
    error| than every pure MPM run's) and within the noise floor (|error| no larger than the other
    packing's |error| plus one standard error of each)."""
    dem = next(r for r in rows if r["form"] == "dem")
    noise = next((r for r in rows if r["form"] == "dem_noise"), None)
    mpm = [abs(r["error"]) for r in rows if r["form"].startswith("mpm")]
    out = []
    for r in rows:
        if r["form"] != "hybrid":
            continue
        within = None
        if noise is not None:
            within = abs(r["error"]) <= abs(noise["error"]) + r["error_se"] + noise["error_se"]
        out.append(dict(label=r["label"], left_of_dem=r["wall_s"] < dem["wall_s"],
                        below_mpm=bool(mpm) and abs(r["error"]) < min(mpm), within_noise=within))
    return out


def plot(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    dem = next(r for r in rows if r["form"] == "dem")
    noise = next((r for r in rows if r["form"] == "dem_noise"), None)
    if noise is not None:
        ax.axhspan(0, 100 * abs(noise["error"]), color="0.85", label="noise floor (DEM, another packing)")
    ax.axvline(dem["wall_s"], color="k", ls=":", lw=1, label="DEM wall time")
    ax.plot([dem["wall_s"]], [0.0], "ks", label="LAMMPS DEM (reference)")
    hybrids = sorted((r for r in rows if r["form"] == "hybrid"), key=lambda r: r["wall_s"])
    errors = [100 * abs(r["error"]) for r in hybrids]
    below = [min(e, 100 * r["error_se"]) for e, r in zip(errors, hybrids)]    # |error| is not below zero
    ax.errorbar([r["wall_s"] for r in hybrids], errors, yerr=[below, [100 * r["error_se"] for r in hybrids]],
                fmt="o-", capsize=3, label="hybrid (zone depths), ± 1 s.e.")
    for r in hybrids:
        ax.annotate(r["label"], (r["wall_s"], 100 * abs(r["error"])), textcoords="offset points", xytext=(5, 4),
                    fontsize=7)
    for model, marker in (("drucker_prager", "^"), ("mu_i", "v")):
        mine = [r for r in rows if r["form"] == f"mpm_{model}"]
        if mine:
            ax.plot([r["wall_s"] for r in mine], [100 * abs(r["error"]) for r in mine], marker,
                    label=f"pure MPM, {MPM_LABELS[model]}")
            for r in mine:
                ax.annotate(f"{r['cell_d']:g} d", (r["wall_s"], 100 * abs(r["error"])), textcoords="offset points",
                            xytext=(5, -9), fontsize=7)
    top = max(100 * (abs(r["error"]) + r["error_se"]) for r in rows)
    ax.set_yscale("symlog", linthresh=1.0)    # linear below 1 %, where the hybrid and the noise floor lie
    ax.set(xscale="log", ylim=(0, 1.5 * top), xlabel="wall time, s", ylabel="|discharge rate error| vs DEM, %",
           title=title)
    ax.title.set_fontsize(10)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write(saved: dict, out: Path) -> None:
    """The report (out, the notes below its marker kept) and the plot beside it, from the saved figures."""
    rows, n, tdis = saved["rows"], saved["width_d"], saved["tdis"]
    title = f"2D silo W = {n} d, {rows[0]['grains']} disks: error against run time ({tdis:g} s of discharge)"
    plot(rows, out.with_suffix(".png"), title)
    table = ["# The deep 2D silo: error against run time", "",
             f"`{saved['command']}`, {saved['date']}: W = {n} d, H = {saved['height_d']} d, D = {saved['orifice_d']} d, "
             f"d = {D * 1e3:g} mm, {rows[0]['grains']} disks, {tdis:g} s of discharge, each rate over the same steady "
             "window. The DEM and the hybrids ran in the same minutes (interleaved), the pure MPM runs after them, "
             f"the other packing's DEM untimed; LAMMPS on {saved['np']} ranks, the MPM on {saved['threads']} threads, "
             "a 2-core machine. Error: the rate's relative difference from the DEM's, ± its standard error from the "
             "runs' own fluctuation. The pure MPM runs start from the fill at rest with the calibrated continuum "
             "(input_decks/materials/disks_2d.toml) and the grains' wall friction.", "",
             f"![error against run time]({out.with_suffix('.png').name})", "",
             "| run | wall s | speedup over DEM | rate (kg/s/m) | error vs DEM | continuum share |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        share = f"{r['continuum_share']:.0%}" if "continuum_share" in r else ""
        wall = f"{r['wall_s']:.0f}" + (" (untimed)" if r["form"] == "dem_noise" else "")
        speed = "" if r["form"] == "dem_noise" else f"{r['speedup']:.2f}x"
        table.append(f"| {r['label']} | {wall} | {speed} | {r['rate']:.3f} | {r['error']:+.1%} ± "
                     f"{r['error_se']:.1%} | {share} |")
    table += ["", "| hybrid | left of the DEM | below every pure MPM run | within the noise floor |",
              "| --- | --- | --- | --- |"]
    yes = lambda v: "-" if v is None else ("yes" if v else "no")  # noqa: E731
    table += [f"| {v['label']} | {yes(v['left_of_dem'])} | {yes(v['below_mpm'])} | {yes(v['within_noise'])} |"
              for v in saved["verdicts"]]
    write_report(out, "\n".join(table))
    print("\n".join(table))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--width-d", type=int, default=40, help="silo width in grain diameters (H = 3 W, D = 10 d)")
    ap.add_argument("--depths", default="12,24", help="the hybrid's other zone depths (fix keyword depth), d")
    ap.add_argument("--cells", default="2,1", help="the pure MPM runs' cells, d")
    ap.add_argument("--models", default="drucker_prager,mu_i")
    ap.add_argument("--noise-seed", type=int, default=2, help="the other packing's seed (0 = no noise floor)")
    ap.add_argument("--np", dest="np_", type=int, default=2, help="LAMMPS ranks")
    ap.add_argument("--threads", type=int, default=2, help="the MPM's OpenMP threads (hybrid and pure MPM)")
    ap.add_argument("--tdis", type=float, default=1.0, help="s of discharge")
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--hcell", default="0", help="the hybrid's cell, m, or 0 (the fix's, from the grains)")
    ap.add_argument("--work", type=Path, default=REPO / "runs" / "silo_front")
    ap.add_argument("--out", type=Path, default=None, help="the report (default bench/results/silo_front_<W>.md)")
    ap.add_argument("--render", action="store_true", help="only write the report and the plot again from the JSON")
    a = ap.parse_args()
    if a.out is None:
        a.out = RESULTS / f"silo_front_{a.width_d}.md"
    if a.render:
        saved = json.loads(a.out.with_suffix(".json").read_text())
        write(saved, a.out)
        return 0
    n = a.width_d
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    os.environ["OMP_NUM_THREADS"] = str(a.threads)
    depths = tuple(((("depth_d", float(x)),) for x in a.depths.split(",") if x))
    hybrid_rows = run_silo(Silo2d(a.np_, a.seed, a.tdis, a.hcell), n, a.threads, a.work, depths)
    first = hybrid_rows[0]
    dem = SimpleNamespace(rate=first["rate_dem"], rate_se=first["rate_se_dem"] * first["rate_dem"])
    rows = [dict(form="dem", label="LAMMPS DEM", wall_s=first["dem_wall_s"], rate=first["rate_dem"], error=0.0,
                 error_se=0.0, speedup=1.0, grains=first["grains"])]
    for r in hybrid_rows:
        depth = r.get("depth_d")
        rows.append(dict(form="hybrid", label="fix's zones" if depth is None else f"depth {depth:g} d",
                         depth_d=depth, wall_s=r["hybrid_wall_s"], rate=r["rate_hybrid"], error=r["error"],
                         error_se=r["error_se"], speedup=r["speedup"], predicted_speedup=r["predicted_speedup"],
                         continuum_share=r["continuum_share"]))
        print(f"hybrid, {rows[-1]['label']}: {r['speedup']:.2f}x, rate {r['error']:+.1%}", flush=True)
    if a.noise_seed:
        other = Silo2d(a.np_, a.noise_seed, a.tdis, a.hcell)
        other.prepare(n, a.work)
        dem2 = other.run(n, a.work / f"dem_{n}_seed{a.noise_seed}")
        rows.append(dict(form="dem_noise", label=f"LAMMPS DEM, packing {a.noise_seed}", wall_s=dem2.wall_time,
                         rate=dem2.rate, error=dem2.rate / dem.rate - 1, error_se=rate_ratio_se(dem2, dem),
                         grains=dem2.grains))
        print(f"DEM from packing {a.noise_seed}: rate {rows[-1]['error']:+.1%}", flush=True)
    for model in a.models.split(","):
        for cell in (float(c) for c in a.cells.split(",")):
            silo = MpmSilo(**silo_size(n), model=model, cell=cell * D, tdis=a.tdis)
            res = run_mpm_silo(silo, a.work / f"mpm_{model}_{cell:g}d", threads=a.threads, timeout=4 * 3600)
            rows.append(dict(form=f"mpm_{model}", label=f"pure MPM, {MPM_LABELS[model]}, cell {cell:g} d",
                             cell_d=cell, wall_s=res["wall_time"], rate=res["rate"],
                             error=res["rate"] / rows[0]["rate"] - 1,
                             error_se=rate_ratio_se(SimpleNamespace(**res), dem), speedup=rows[0]["wall_s"] / res["wall_time"],
                             points=res["points_left"]))
            print(f"{rows[-1]['label']}: rate {rows[-1]['error']:+.1%}, {res['wall_time']:.0f} s", flush=True)
    command = (f"bench/silo_front.py --width-d {n} --depths {a.depths} --cells {a.cells} --models {a.models} "
               f"--noise-seed {a.noise_seed} --np {a.np_} --threads {a.threads} --tdis {a.tdis} --seed {a.seed}")
    saved = dict(date=stamp, command=command, width_d=n, height_d=DEPTH * n, orifice_d=ORIFICE, np=a.np_,
                 threads=a.threads, tdis=a.tdis, rows=rows, verdicts=verdicts(rows))
    a.out.with_suffix(".json").write_text(json.dumps(saved, indent=1))
    write(saved, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
