#!/usr/bin/env python3
"""Stability suite: stiff and extreme cases for both sides of the hybrid, each of which must
either run stable or stop with a clear error before it goes unstable.

    tools/stability_suite.py --out /tmp/stability [--np 2] [--only NAME ...]

Writes <out>/stability.md (a table) and <out>/stability.json; exit status 0 when every case
ended as expected. Cases (all 2D, a few seconds each):

  continuum (mpm_solver, Drucker-Prager unless noted)
    stiff_continuum          Young's modulus x100 over the collapse default; automatic step
    stiff_continuum_fixed_dt the same with a fixed [time] dt that is stable only for the
                             default modulus: refused, naming the stable step
    impact_continuum         a block shot at 60 m/s into a bed in a closed box
    impact_fixed_dt          the same with a fixed dt stable at rest but not at 60 m/s: stops
                             when the speed makes it unstable, naming the stable step
    dilute_and_back          a mu(I) block dropped from 0.1 m: free fall, splash below the
                             critical density (stress-free), and back to a dense heap
    near_empty_cell          a single material point alone in its cell, falling onto the floor
    high_shear               a mu(I) layer sheared at 1000/s between the floor and a lid
    free_collision           two blocks meeting head-on at 10 m/s without gravity or walls
  grains (lmp_hybrid + mpm_solver, input_decks/stability/grain_bed_2d.lmp: a bed whose lower
  part is continuum)
    stiff_grains_deck_step   kn x100 at the deck's step: refused, naming the safe step
    stiff_grains_safe_step   kn x100 at the step that error named
    impact_grains            kn x100, safe step, a grain shot at 50 m/s into the bed

Stable means: the run reached its end; every recorded state is finite; the mass is exact
(relative drift below MASS_TOL); the kinetic plus gravitational energy never exceeds its
initial value plus ENERGY_TOL of the energy scale (initial kinetic energy + M g H of the box;
for the layer the lid drives, the layer's kinetic energy at the lid's speed, which the lid's
work may supply: the bound is then that scale + ENERGY_TOL); where nothing external acts
(free_collision) the momentum is exact (drift below MOMENTUM_TOL of sum m|v|).
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import tomli_w
from tqdm import tqdm

from hgtools.logs import thermo_rows
from hgtools.runner import run_deck, run_mpm
from mpm_results import load_run

REPO = Path(__file__).resolve().parent.parent
GRAIN_DECK = REPO / "input_decks" / "stability" / "grain_bed_2d.lmp"
G = 9.81
MASS_TOL = 1e-12
MOMENTUM_TOL = 1e-10
ENERGY_TOL = 0.05


@dataclass
class Outcome:
    name: str
    side: str
    what: str
    expected: str               # "stable" or "stopped"
    status: str = ""            # "stable", "stopped", or "FAILED: ..."
    detail: str = ""
    wall: float = 0.0
    figures: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == self.expected


# ----------------------------------------------------------------------------- continuum
def box_scene(end_time: float, blocks: list, materials: list, gravity=(0.0, -G), lower=(0.0, 0.0),
              upper=(0.2, 0.2), cell=0.005, time_table: dict | None = None, boundaries: list | None = None,
              interval: float | None = None) -> dict:
    scene = {
        "dimension": 2, "end_time": end_time, "gravity": list(gravity),
        "grid": {"cell_size": cell, "lower": list(lower), "upper": list(upper), "walls": "slip"},
        "output": {"interval": interval if interval is not None else end_time / 20},
        "material": materials, "block": blocks,
    }
    if time_table:
        scene["time"] = time_table
    if boundaries:
        scene["boundary"] = boundaries
    return scene


def sand(youngs=2.0e6, name="sand") -> dict:
    return {"name": name, "model": "drucker_prager", "density": 1600.0, "youngs_modulus": youngs,
            "poisson_ratio": 0.3, "friction_angle": 30.0}


def beads(name="beads") -> dict:
    # glass beads (docs/design.md section 4): mu(I) with Jop et al.'s constants, disconnected below
    # the critical density
    return {"name": name, "model": "mu_i", "density": 1500.0, "youngs_modulus": 2.0e6, "poisson_ratio": 0.3,
            "grain_diameter": 0.001, "grain_density": 2500.0, "critical_density": 1400.0}


def block(lower, upper, material="sand", velocity=None, ppc=4, geostatic=False) -> dict:
    b = {"material": material, "shape": "box", "lower": list(lower), "upper": list(upper), "points_per_cell": ppc}
    if velocity is not None:
        b["velocity"] = list(velocity)
    if geostatic:
        b["geostatic"] = True
    return b


COLUMN = block((0.0, 0.0), (0.05, 0.1), geostatic=True)


def continuum_cases() -> list[tuple[str, str, str, Callable[[], dict], str, dict]]:
    """(name, what, expected, scene builder, expected message, checks)."""
    bed = block((0.0, 0.0), (0.2, 0.04))
    shot = block((0.08, 0.08), (0.12, 0.12), velocity=(0.0, -60.0))
    lid_speed = 20.0
    return [
        ("stiff_continuum", "Young's modulus x100 (2e8 Pa), automatic step", "stable",
         lambda: box_scene(0.05, [COLUMN], [sand(2.0e8)]), "", {}),
        ("stiff_continuum_fixed_dt", "Young's modulus x100 with a fixed step stable for x1", "stopped",
         lambda: box_scene(0.05, [COLUMN], [sand(2.0e8)], time_table={"dt": 3.0e-5}),
         "is above the stable step", {}),
        ("impact_continuum", "a block at 60 m/s into a bed (closed box)", "stable",
         lambda: box_scene(0.01, [bed, shot], [sand()], interval=0.0005), "", {}),
        ("impact_fixed_dt", "the impact with a fixed step stable at rest, not at 60 m/s", "stopped",
         lambda: box_scene(0.01, [bed, shot], [sand()], time_table={"dt": 2.0e-5}, interval=0.0005),
         "is above the stable step", {}),
        ("dilute_and_back", "mu(I) block dropped from 0.1 m: free fall, dilute splash, heap", "stable",
         lambda: box_scene(0.4, [block((0.05, 0.1), (0.1, 0.15), "beads")], [beads()], upper=(0.3, 0.2)),
         "", {}),
        ("near_empty_cell", "one material point alone in its cell, falling onto the floor", "stable",
         lambda: box_scene(0.2, [COLUMN, block((0.15, 0.1), (0.1525, 0.1025), ppc=1)], [sand()]), "", {}),
        ("high_shear", f"mu(I) layer sheared at {lid_speed / 0.02:g}/s by a lid at {lid_speed:g} m/s", "stable",
         lambda: box_scene(0.004, [block((0.0, 0.0), (0.3, 0.02), "beads")], [beads()], upper=(0.3, 0.1),
                           boundaries=[{"type": "plane", "contact": "sticky", "point": [0.0, 0.0], "normal": [0.0, 1.0]},
                                       {"type": "plane", "contact": "sticky", "separating": False,
                                        "point": [0.0, 0.02], "normal": [0.0, -1.0], "velocity": [lid_speed, 0.0]}],
                           interval=0.0002),
         # driven: the lid's work may raise the energy, up to the layer moving with the lid
         "", {"energy_scale": 0.5 * 1500.0 * 0.3 * 0.02 * lid_speed ** 2, "energy_limit": 1 + ENERGY_TOL}),
        ("free_collision", "two blocks head-on at 10 m/s, no gravity, no walls reached", "stable",
         lambda: box_scene(0.01, [block((0.1, 0.08), (0.15, 0.12), velocity=(10.0, 0.0)),
                                  block((0.25, 0.08), (0.3, 0.12), velocity=(-10.0, 0.0))],
                           [sand()], gravity=(0.0, 0.0), upper=(0.4, 0.2), interval=0.0005),
         "", {"momentum": True}),
    ]


def frame_figures(run, gravity) -> dict:
    """Mass, momentum, kinetic + gravitational energy and finiteness per frame."""
    g = np.asarray(gravity)
    mass, momentum, energy, kinetic, finite = [], [], [], [], True
    scale_mv = 0.0
    for i in range(len(run)):
        f = run.frame(i, ["position", "velocity", "mass", "stress"])
        m, x, v = f["mass"], f["position"], f["velocity"]
        finite = finite and all(np.isfinite(a).all() for a in (x, v, f["stress"]))
        mass.append(m.sum())
        momentum.append((m[:, None] * v).sum(axis=0))
        scale_mv = max(scale_mv, float((m * np.linalg.norm(v, axis=1)).sum()))
        kinetic.append(0.5 * float((m * (v ** 2).sum(axis=1)).sum()))
        energy.append(kinetic[-1] - float((m[:, None] * x * g).sum()))
    return dict(mass=np.array(mass), momentum=np.array(momentum), energy=np.array(energy), kinetic0=kinetic[0],
                finite=finite, scale_mv=scale_mv, frames=len(run))


def judge(out: Outcome, finite: bool, mass: np.ndarray, energy: np.ndarray, energy_scale: float,
          momentum: np.ndarray | None = None, scale_mv: float = 0.0, energy_limit: float = ENERGY_TOL) -> None:
    """Sets the outcome from the recorded states (see the module doc for the criteria)."""
    mass_drift = float(np.max(np.abs(mass - mass[0])) / mass[0])
    rise = float(np.max(energy - energy[0]) / energy_scale)
    out.figures.update(mass_drift=mass_drift, energy_rise=rise, energy_scale=energy_scale)
    problems = []
    if not finite:
        problems.append("non-finite state")
    if mass_drift > MASS_TOL:
        problems.append(f"mass drift {mass_drift:.2e}")
    if rise > energy_limit:
        problems.append(f"energy rose by {rise:.3f} of its scale")
    if momentum is not None:
        drift = float(np.max(np.linalg.norm(momentum - momentum[0], axis=1)) / scale_mv)
        out.figures["momentum_drift"] = drift
        if drift > MOMENTUM_TOL:
            problems.append(f"momentum drift {drift:.2e}")
    out.status = "stable" if not problems else "FAILED: " + "; ".join(problems)
    out.detail = (f"mass drift {mass_drift:.1e}, energy rise {rise:+.3f} of scale"
                  + (f", momentum drift {out.figures['momentum_drift']:.1e}" if momentum is not None else ""))


def stopped(out: Outcome, text: str, message: str, ran: bool) -> None:
    """A run expected to stop: it must have stopped with `message` (and a readable error line)."""
    line = next((ln.strip() for ln in text.splitlines() if message in ln), "")
    if ran:
        out.status = "FAILED: ran to the end instead of stopping"
    elif line:
        out.status, out.detail = "stopped", line
    else:
        tail = " | ".join(text.strip().splitlines()[-3:])
        out.status = f"FAILED: stopped without the expected message ({message!r}): {tail}"


def run_continuum(name, what, expected, build, message, checks, out_dir: Path, timeout: float) -> Outcome:
    out = Outcome(name, "continuum", what, expected)
    work = out_dir / name
    work.mkdir(parents=True, exist_ok=True)
    scene = build()
    path = work / "scene.toml"
    path.write_text(tomli_w.dumps(scene))
    done = run_mpm(path, "--output", work / "output", "--threads", "1", timeout=timeout)
    proc, out.wall = done.proc, done.wall
    text = proc.stdout + proc.stderr
    if expected == "stopped":
        stopped(out, text, message, proc.returncode == 0)
        return out
    if proc.returncode != 0:
        out.status = "FAILED: " + " | ".join(text.strip().splitlines()[-2:])
        return out
    fig = frame_figures(load_run(work / "output"), scene["gravity"])
    height = scene["grid"]["upper"][1] - scene["grid"]["lower"][1]
    scale = checks.get("energy_scale",
                       fig["kinetic0"] + fig["mass"][0] * float(np.linalg.norm(scene["gravity"])) * height)
    judge(out, fig["finite"], fig["mass"], fig["energy"], scale,
          fig["momentum"] if checks.get("momentum") else None, fig["scale_mv"], checks.get("energy_limit", ENERGY_TOL))
    out.figures["frames"] = fig["frames"]
    return out


# -------------------------------------------------------------------------------- grains
GRAIN_CASES = ("stiff_grains_deck_step", "stiff_grains_safe_step", "impact_grains")
THERMO = ("Step", "Atoms", "KinEng", "f_couple[8]", "f_couple[9]", "f_couple[10]", "f_couple[15]")


def run_grains(name, what, expected, variables: dict, message: str, out_dir: Path, np_: int,
               timeout: float) -> Outcome:
    out = Outcome(name, "grains", what, expected)
    work = out_dir / name
    work.mkdir(parents=True, exist_ok=True)
    log = work / "log.lammps"
    done = run_deck("hybrid", GRAIN_DECK, variables, log, np_=np_, timeout=timeout)
    proc, out.wall = done.proc, done.wall
    text = done.text() + proc.stdout + proc.stderr
    if expected == "stopped":
        stopped(out, text, message, proc.returncode == 0)
        return out
    if proc.returncode != 0:
        out.status = "FAILED: " + " | ".join(ln for ln in text.splitlines() if "ERROR" in ln)[:400]
        return out
    rows = np.array([[r[c] for c in THERMO] for r in thermo_rows(text, require="f_couple[15]")])
    if len(rows) < 3:
        out.status = "FAILED: no thermo output"
        return out
    mass = rows[:, 3]
    kinetic = rows[:, 2] + rows[:, 6]    # grains + continuum
    # the energy that can turn kinetic: the initial kinetic energy and everything falling the box
    scale = kinetic[0] + mass[0] * G * 0.1
    judge(out, bool(np.isfinite(rows).all()), mass, kinetic, scale)
    out.detail += f", {int(rows[-1, 0])} steps"
    return out


def grain_cases(out_dir: Path, np_: int, timeout: float) -> list[Outcome]:
    # 1.1 steps per contact: velocity Verlet is unstable there (below pi/2), so the fix refuses it
    refused = run_grains("stiff_grains_deck_step", "kn x100 (1e5 N/m) at 1.5x the deck's step (1.5e-5 s)", "stopped",
                         {"knfac": 100, "dt": 1.5e-5, "nsteps": 100}, "Use timestep", out_dir, np_, timeout)
    m = re.search(r"Use timestep (\S+) \(tc/20\)", refused.detail)
    safe = float(m.group(1)) if m else 1.0e-6
    cases = [refused,
             run_grains("stiff_grains_safe_step", f"kn x100 at the step the refusal named ({safe:.3g} s)", "stable",
                        {"knfac": 100, "dt": safe, "nsteps": 3000}, "", out_dir, np_, timeout),
             run_grains("impact_grains", f"kn x100, step {safe:.3g} s, a grain shot at 50 m/s into the bed", "stable",
                        {"knfac": 100, "dt": safe, "nsteps": 3000, "vshot": 50}, "", out_dir, np_, timeout)]
    if not m:
        cases[0].status = "FAILED: the refusal named no safe step"
    return cases


# -------------------------------------------------------------------------------- report
def report(outcomes: list[Outcome]) -> str:
    lines = ["# Stability suite", "",
             f"`tools/stability_suite.py`, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. "
             "Each case either runs stable (finite, mass exact, kinetic + gravitational energy bounded, "
             "momentum exact where nothing external acts) or stops with a clear error before it goes "
             "unstable.", "",
             "| case | side | what | expected | outcome | wall s | detail |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for o in outcomes:
        detail = o.detail.replace("|", "/")
        lines.append(f"| {o.name} | {o.side} | {o.what} | {o.expected} | {o.status} | {o.wall:.1f} | {detail} |")
    passed = sum(o.ok for o in outcomes)
    lines += ["", f"{passed} of {len(outcomes)} cases ended as expected."]
    return "\n".join(lines) + "\n"


def run_suite(out_dir: Path, np_: int = 2, only: list[str] | None = None, timeout: float = 600,
              progress: bool = True) -> list[Outcome]:
    """Runs the cases (all, or those named in `only`) and writes the report into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    continuum = [c for c in continuum_cases() if only is None or c[0] in only]
    want_grains = only is None or any(n in GRAIN_CASES for n in only)
    outcomes = []
    with tqdm(total=len(continuum) + (3 if want_grains else 0), desc="stability", unit="case",
              disable=not progress) as bar:
        for case in continuum:
            bar.set_postfix_str(case[0])
            outcomes.append(run_continuum(*case, out_dir, timeout))
            bar.update()
        if want_grains:    # one sequence: the safe step comes from the refusal
            bar.set_postfix_str("grains")
            outcomes += [o for o in grain_cases(out_dir, np_, timeout) if only is None or o.name in only]
            bar.update(3)
    (out_dir / "stability.md").write_text(report(outcomes))
    (out_dir / "stability.json").write_text(json.dumps([dict(asdict(o), ok=o.ok) for o in outcomes], indent=1))
    return outcomes


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--np", dest="np_", type=int, default=2, help="LAMMPS ranks of the grain cases")
    p.add_argument("--only", nargs="*", default=None, metavar="NAME", help="run only these cases")
    p.add_argument("--timeout", type=float, default=600, help="s per case")
    args = p.parse_args(argv)
    known = [c[0] for c in continuum_cases()] + list(GRAIN_CASES)
    unknown = [n for n in args.only or [] if n not in known]
    if unknown:
        p.error(f"unknown case(s) {', '.join(unknown)} (known: {', '.join(known)})")
    outcomes = run_suite(Path(args.out), args.np_, args.only, args.timeout)
    print(report(outcomes))
    return 0 if outcomes and all(o.ok for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
