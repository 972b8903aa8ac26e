#!/usr/bin/env python3
"""Pure-DEM references of a reduced quasi-3D (slab) granular column collapse, run with
LAMMPS (input_decks/column_collapse/dem_3d.lmp) or LIGGGHTS (liggghts_3d.in), the twin
decks sharing one parameter set and one contact law (see the decks' headers for the
LAMMPS <-> LIGGGHTS mapping).

This driver writes the initial grains (a data file both codes read: frozen floor spheres
and a loose lattice of polydisperse spheres to pour), runs one code's deck, reads its
dumps and measures the normalised runout (Lf - L0)/L0 and the final surface profile with
the front definition of tools/dem_collapse.py: the deposit is the cluster of flowing grains
connected through contacts (gap < CONTACT_GAP d) to the grain nearest the back wall, here
in 3D with the periodic z direction, and Lf = max(x + r) over it. The surface profile is
dem_collapse.surface_profile (max y + r per x bin of 2 d) over the connected deposit.

    tools/dem3d_collapse.py --code lammps   --np 2 --out /tmp/d3_lmp
    tools/dem3d_collapse.py --code liggghts --np 2 --out /tmp/d3_lig
"""
from __future__ import annotations

import argparse
import math
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from column_collapse import published_runout_range  # noqa: E402
from sphere_data import write_spheres  # noqa: E402
from dem_collapse import (connected_deposit, deck_vars, max_overlap, print_result, read_dump,  # noqa: E402
                          surface_profile)

REPO = Path(__file__).resolve().parent.parent
DECKS = {
    "lammps": REPO / "input_decks" / "column_collapse" / "dem_3d.lmp",
    "liggghts": REPO / "input_decks" / "column_collapse" / "liggghts_3d.in",
    "hybrid": REPO / "input_decks" / "column_collapse" / "dem_3d.lmp",   # + hybrid_3d.lmp, lmp_hybrid
}
HYBRID_DECK = REPO / "input_decks" / "column_collapse" / "hybrid_3d.lmp"
EXECUTABLES = {"lammps": "lmp", "liggghts": "liggghts", "hybrid": "lmp"}

FLOOR_SPACING = 1.2      # floor sphere spacing in x and z, in d (a 0.9 d grain cannot pass)
LATTICE_SPACING = 1.16   # loose pouring lattice spacing (x, y), in d (> dmax + 2 * jitter)
LATTICE_JITTER = 0.025   # random offset of the lattice sites, +- in d, per axis
PHI_EST = 0.60           # packing fraction assumed to size the pour (trimmed 8 % extra)


def runout_upper(aspect: float) -> float:
    return 1.8 * aspect if aspect < 1.8 else 2.3 * aspect ** (2.0 / 3.0)


def domain_length(aspect: float, width: float, d: float) -> float:
    """x of the end wall: as the decks' default (twice the published upper bound, margin)."""
    return width * (1.0 + 2.0 * runout_upper(aspect)) + 20 * d


def pour_lattice(length: float, W: float, d: float, volume: float) -> tuple:
    """The loose pouring lattice of a slab (periodic or walled) of thickness W: x sites from
    `margin` to length - margin at LATTICE_SPACING d, z sites filling W (no two closer than
    the largest grain plus the jitter), and the number of grains that fill `volume` at
    PHI_EST, 8 % extra to trim. Returns (xs, zs, margin, need)."""
    s = LATTICE_SPACING * d
    nz = max(1, int(round(W / s)))
    sz = W / nz
    if sz < 1.1 * d + 2 * LATTICE_JITTER * d:
        nz -= 1
        sz = W / nz
    margin = 0.55 * 1.1 * d + LATTICE_JITTER * d
    xs = np.arange(margin, length - margin + 1e-12, s)
    zs = (np.arange(nz) + 0.5) * sz
    vmean = math.pi / 6 * d ** 3 * 1.01          # <D^3> for D uniform in [0.9, 1.1] d
    return xs, zs, margin, int(math.ceil(1.08 * PHI_EST * volume / vmean))


def write_data(path: Path, aspect: float, width: float, d: float, thickness_d: int,
               seed: int, rho: float = 2500.0) -> dict:
    """Writes the initial data file (atom_style sphere: id type diameter density x y z)
    that both decks read. Floor: frozen spheres of diameter d on a square lattice of spacing
    FLOOR_SPACING d in x and z, centres at y = -d/2, over the whole domain. Grains: diameters
    uniform in [0.9, 1.1] d, on a lattice of spacing LATTICE_SPACING d in x and y and
    W / round(W / (LATTICE_SPACING d)) in z, offset by up to +-LATTICE_JITTER d, between
    x = 0 and L0, from y = 0.6 d up until about 1.08 * PHI_EST * L0 H0 W of grain volume."""
    rng = np.random.default_rng(seed)
    H0 = aspect * width
    W = thickness_d * FLOOR_SPACING * d         # slab thickness: a whole number of floor rows
    length = domain_length(aspect, width, d)
    # floor
    fs = FLOOR_SPACING * d
    fx = np.arange(0.5 * fs - 2 * d, length + 2 * d, fs)
    fz = (np.arange(thickness_d) + 0.5) * fs
    FX, FZ = np.meshgrid(fx, fz, indexing="ij")
    floor = np.column_stack([FX.ravel(), np.full(FX.size, -0.5 * d), FZ.ravel()])
    # grains
    s = LATTICE_SPACING * d
    xs, zs, margin, need = pour_lattice(width, W, d, width * H0 * W)
    per_layer = len(xs) * len(zs)
    layers = int(math.ceil(need / per_layer))
    ys = 0.6 * d + np.arange(layers) * s
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    grains = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    grains += rng.uniform(-LATTICE_JITTER * d, LATTICE_JITTER * d, grains.shape)
    grains[:, 2] %= W
    diam = rng.uniform(0.9 * d, 1.1 * d, len(grains))
    ytop = ys[-1] + 4 * d
    write_spheres(path, "Quasi-3D column collapse grains (tools/dem3d_collapse.py)",
                  ((-2 * d, length + 2 * d), (-1.5 * d, ytop), (0.0, W)),
                  [("grains", 1, diam, rho, grains), ("floor", 2, d, rho, floor)], types=4)
    return dict(thickness=W, length=length, poured=len(grains), floor=len(floor), ytop=ytop)


def analyse3(final: dict, initial: dict, width: float, d: float, period_z: float | None) -> dict:
    """period_z: the slab's period, or None between side walls."""
    g = final["type"] == 1
    pos = np.column_stack([final["x"][g], final["y"][g], final["z"][g]])
    r = final["radius"][g]
    mask = connected_deposit(pos, r, d, period_z)
    edge = pos[:, 0] + r
    front = float(edge[mask].max())
    gi = initial["type"] == 1
    speed = np.sqrt(final["vx"][g] ** 2 + final["vy"][g] ** 2 + final["vz"][g] ** 2)
    return dict(
        grains=int(g.sum()),
        runout=(front - width) / width,
        runout_p995=(float(np.percentile(edge, 99.5)) - width) / width,
        runout_max=(float(edge.max()) - width) / width,
        front=front,
        height=float((initial["y"][gi] + initial["radius"][gi]).max()),
        final_height=float(np.max((pos[:, 1] + r)[pos[:, 0] < 2 * d], initial=0.0)),  # 0: continuum there
        max_speed=float(speed.max()),
        max_speed_deposit=float(speed[mask].max()),
        max_overlap_initial=max_overlap(initial, d, period_z),
        max_overlap_final=max_overlap(final, d, period_z),
        detached=int((~mask).sum()),
        profile=surface_profile(pos[mask, 0], pos[mask, 1], r[mask], 2 * d, front),
    )


@dataclass
class Dem3dResult:
    code: str
    aspect: float
    width: float
    d: float
    thickness: float
    grains: int
    runout: float
    runout_p995: float
    runout_max: float
    front: float
    height: float
    final_height: float
    max_speed: float
    max_speed_deposit: float
    max_overlap_initial: float
    max_overlap_final: float
    detached: int
    ke_per_grain: float
    ke_rest: float
    collapse_time: float          # simulated time from the gate removal to rest, s
    wall_time: float              # s, the whole run (pour, settle, collapse)
    collapse_wall: float          # s, the collapse alone (the codes' loop times after the gate opens)
    collapse_steps: int
    params: dict = field(default_factory=dict)    # kn, kt, gamma_n, ... as the deck printed them
    published: tuple = ()
    profile: list = field(default_factory=list)
    log: str = ""

    @property
    def at_rest(self) -> bool:
        return self.ke_per_grain < self.ke_rest

    def summary(self) -> str:
        lo, hi = self.published
        return (f"{self.code}: slab a = {self.aspect:g}, L0 = {self.width:g} m, W = {self.thickness:.4g} m, "
                f"{self.grains} grains, wall time {self.wall_time:.1f} s (collapse {self.collapse_wall:.1f} s, "
                f"{self.collapse_steps} steps)\n"
                f"  (Lf - L0)/L0 = {self.runout:.3f} (99.5 % {self.runout_p995:.3f}, max {self.runout_max:.3f}, "
                f"{self.detached} detached); published {lo:.2f} .. {hi:.2f}\n"
                f"  H0 = {self.height:.4g} m, final height at wall {self.final_height:.4g} m, "
                f"collapse time {self.collapse_time:.3f} s, KE/grain {self.ke_per_grain:.2e} J "
                f"(rest < {self.ke_rest:.2e}), max speed in deposit {self.max_speed_deposit:.2e} m/s,\n"
                f"  max overlap/d settled {self.max_overlap_initial:.4f}, final {self.max_overlap_final:.4f}")


def _num(pattern: str, text: str) -> float:
    m = re.search(pattern, text, re.M)
    if not m:
        raise RuntimeError(f"pattern {pattern!r} not in the log")
    return float(m.group(1))


def run(code: str = "lammps", aspect: float = 2.0, width: float = 0.03, d: float = 0.002,
        thickness_d: int = 4, np_: int = 1, out: str | Path | None = None, seed: int = 2024,
        timeout: float = 600, extra_vars: dict | None = None, exe: str | None = None) -> Dem3dResult:
    """Writes the data file, runs `code`'s deck and analyses its dumps.
    thickness_d: slab thickness W in floor rows (W = thickness_d * 1.2 d).
    code "hybrid": dem_3d.lmp with its hybrid twin (hybrid_3d.lmp, side walls: walls 1) through
    tools/hybrid_launch.py; the result holds the grains, the points are in <out>/frames."""
    deck = DECKS[code]
    exe = exe or shutil.which(EXECUTABLES[code])
    if exe is None:
        raise FileNotFoundError(f"{EXECUTABLES[code]} not on PATH")
    # absolute: the codes run in it (cwd), and the paths they are given must hold there too
    out = (Path(out) if out else Path.cwd() / f"dem3d_{code}").resolve()
    out.mkdir(parents=True, exist_ok=True)
    for f in ("final.dump", "initial.dump"):
        (out / f).unlink(missing_ok=True)
    geo = write_data(out / "grains.data", aspect, width, d, thickness_d, seed)
    variables = dict(data=out / "grains.data", out=out, aspect=aspect, width=width, d=d,
                     length=f"{geo['length']:.9g}", **(extra_vars or {}))
    if code == "hybrid":
        variables.update(walls=1, hybrid=1, hdeck=HYBRID_DECK)
        variables.update(extra_vars or {})
        cmd = [sys.executable, str(REPO / "tools" / "hybrid_launch.py"), "-np", str(np_), str(deck)]
    else:
        cmd = [exe, "-in", str(deck)]
    cmd += ["-log", str(out / "log.txt"), "-screen", "none"]
    if code == "liggghts":
        cmd.append("-nocite")
    for k, v in variables.items():
        cmd += ["-var", k, str(v)]
    if np_ > 1 and code != "hybrid":
        cmd = [str(REPO / "tools" / "mpirun.sh"), "-np", str(np_)] + cmd
    t0 = time.time()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=out)
    wall = time.time() - t0
    log = (out / "log.txt").read_text(errors="replace") if (out / "log.txt").exists() else ""
    if proc.returncode != 0 or not (out / "final.dump").exists():
        tail = "\n".join(log.splitlines()[-30:])
        raise RuntimeError(f"{code} failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stdout[-2000:]}\n"
                           f"{proc.stderr[-2000:]}\n{tail}")
    walls = code == "hybrid" or int(variables.get("walls", 0)) == 1
    res = analyse3(read_dump(out / "final.dump"), read_dump(out / "initial.dump"), width, d,
                   None if walls else geo["thickness"])
    params = {k: _num(rf"^DEM3D contact:.*\b{re.escape(k)} = (\S+)", log)
              for k in ("kn", "kt", "gamma_n", "gamma_t", "gamma_n(wall)", "gamma_t(wall)")}
    params["dt"] = _num(r"^DEM3D timestep:.*dt = (\S+) s", log)
    if code == "hybrid":    # the continuum's surface too (its points are in the frames)
        from column_collapse import combine_surfaces, points_surface
        from mpm_results import load_run
        points = load_run(out / "frames").frame(-1)["position"][:, :2]
        grains_surface = np.array(res["profile"]).T if res["profile"] else (np.zeros(0), np.zeros(0))
        x, h = combine_surfaces(grains_surface, points_surface(points, float(variables.get("hcell", 2.5 * d)) / 2,
                                                               2 * d))
        res["profile"] = [(float(a), float(b)) for a, b in zip(x, h)]
        near_wall = points[:, 0] < 2 * d
        res["final_height"] = max(res["final_height"], float(np.max(points[near_wall, 1], initial=0.0)))
    lines = "\n".join(ln for ln in log.splitlines() if ln.startswith("DEM3D "))
    # the collapse stage: the loop times after the gate opens (pour and settle are the same work
    # in every code and form, and the hybrid couples only the collapse)
    stage = log[log.rfind("unfix           gate"):]
    loops = re.findall(r"^Loop time of (\S+) on \d+ procs for (\d+) steps", stage, re.M)
    return Dem3dResult(
        code=code, aspect=aspect, width=width, d=d, thickness=geo["thickness"], wall_time=wall,
        collapse_wall=sum(float(t) for t, _ in loops), collapse_steps=sum(int(n) for _, n in loops),
        ke_per_grain=_num(r"^DEM3D collapse end:.*KE/grain = (\S+) J", log),
        ke_rest=_num(r"^DEM3D collapse end:.*rest threshold (\S+) J", log),
        collapse_time=_num(r"^DEM3D collapse end:.*collapse time = (\S+) s", log),
        params=params, published=published_runout_range(aspect), log=lines, **res)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--code", choices=sorted(DECKS), default="lammps")
    p.add_argument("--aspect", type=float, default=2.0)
    p.add_argument("--width", type=float, default=0.03, help="L0, m")
    p.add_argument("--d", type=float, default=0.002)
    p.add_argument("--thickness", type=int, default=4, help="slab thickness in floor rows (1.2 d each)")
    p.add_argument("--np", type=int, default=1, dest="np_")
    p.add_argument("--out", default=None)
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--var", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    res = run(a.code, a.aspect, a.width, a.d, a.thickness, a.np_, a.out, a.seed, extra_vars=deck_vars(p, a.var))
    print_result(res, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
