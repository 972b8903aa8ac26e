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
max(y + r) per x bin of 2 d over the connected deposit (hgtools.collapse.measure, as in 2D).

    tools/dem3d_collapse.py --code lammps   --np 2 --out /tmp/d3_lmp
    tools/dem3d_collapse.py --code liggghts --np 2 --out /tmp/d3_lig
    tools/dem3d_collapse.py --code hybrid_liggghts --np 2 --out /tmp/d3_hl   (LIGGGHTS-hosted hybrid)
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from column_collapse import published_runout_range
from hgtools import cli, logs
from hgtools.collapse import Deposit, measure
from hgtools.grains import FLOOR_SPACING, LATTICE_SPACING, jittered, pour_lattice, read_dump, slab_floor, write_spheres
from hgtools.runner import CODES, HYBRID_CODES, Forms, workdir

FORMS = Forms("column_collapse", hybrid_liggghts="hybrid_3d.liggghts")


def domain_length(aspect: float, width: float, d: float) -> float:
    """x of the end wall: as the decks' default (twice the published upper bound, margin)."""
    return width * (1.0 + 2.0 * published_runout_range(aspect)[1]) + 20 * d


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
    floor = slab_floor(length + 2 * d, thickness_d, d)
    xs, zs, margin, need = pour_lattice(width, W, d, width * H0 * W)
    ys = 0.6 * d + np.arange(int(math.ceil(need / (len(xs) * len(zs))))) * LATTICE_SPACING * d
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    grains, diam = jittered(rng, np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]), d)
    grains[:, 2] %= W
    ytop = ys[-1] + 4 * d
    write_spheres(path, "Quasi-3D column collapse grains (tools/dem3d_collapse.py)",
                  ((-2 * d, length + 2 * d), (-1.5 * d, ytop), (0.0, W)),
                  [("grains", 1, diam, rho, grains), ("floor", 2, d, rho, floor)], types=4)
    return dict(thickness=W, length=length, poured=len(grains), floor=len(floor), ytop=ytop)


@dataclass(kw_only=True)
class Dem3dResult(Deposit):
    code: str
    thickness: float
    collapse_time: float          # simulated time from the gate removal to rest, s
    collapse_wall: float          # s, the collapse alone (the codes' loop times after the gate opens)
    collapse_steps: int
    params: dict = field(default_factory=dict)    # kn, kt, gamma_n, ... as the deck printed them

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


def run(code: str = "lammps", aspect: float = 2.0, width: float = 0.03, d: float = 0.002,
        thickness_d: int = 4, np_: int = 1, out: str | Path | None = None, seed: int = 2024,
        timeout: float = 600, extra_vars: dict | None = None, exe: str | None = None) -> Dem3dResult:
    """Writes the data file, runs `code`'s deck and analyses its dumps.
    thickness_d: slab thickness W in floor rows (W = thickness_d * 1.2 d).
    code "hybrid": dem_3d.lmp with its hybrid twin (hybrid_3d.lmp, side walls: walls 1) through
    tools/hybrid_launch.py; "hybrid_liggghts": liggghts_3d.in with hybrid_3d.liggghts, LIGGGHTS as
    the DEM host (hybrid_launch.py --host liggghts); the result holds the grains, the points are
    in <out>/frames."""
    out = workdir(out, f"dem3d_{code}", ("final.dump", "initial.dump"))
    geo = write_data(out / "grains.data", aspect, width, d, thickness_d, seed)
    variables = dict(data=out / "grains.data", out=out, aspect=aspect, width=width, d=d,
                     length=f"{geo['length']:.9g}", **(extra_vars or {}))
    done = FORMS.run(code, variables, out / "log.txt", {"walls": 1, **(extra_vars or {})}, np_=np_, exe=exe,
                     timeout=timeout)
    log = done.check("in the collapse", out / "final.dump")
    walls = code in HYBRID_CODES or int(variables.get("walls", 0)) == 1
    res = measure(read_dump(out / "final.dump"), read_dump(out / "initial.dump"), width, d,
                  None if walls else geo["thickness"])
    if code in HYBRID_CODES:    # the continuum's surface too (its points are in the frames)
        from column_collapse import combine_surfaces, points_surface
        from mpm_results import load_run
        points = load_run(out / "frames").frame(-1)["position"][:, :2]
        grains_surface = np.array(res["profile"]).T if res["profile"] else (np.zeros(0), np.zeros(0))
        x, h = combine_surfaces(grains_surface, points_surface(points, float(variables.get("hcell", 2.5 * d)) / 2,
                                                               2 * d))
        res["profile"] = [(float(a), float(b)) for a, b in zip(x, h)]
        near_wall = points[:, 0] < 2 * d
        res["final_height"] = max(res["final_height"], float(np.max(points[near_wall, 1], initial=0.0)))
    # the collapse stage: the loop times after the gate opens (pour and settle are the same work
    # in every code and form, and the hybrid couples only the collapse)
    steps, seconds = logs.loops(log, after="unfix           gate")
    end = r"^DEM3D collapse end:.*"
    return Dem3dResult(
        code=code, aspect=aspect, width=width, d=d, thickness=geo["thickness"], wall_time=done.wall,
        collapse_wall=seconds, collapse_steps=steps,
        ke_per_grain=logs.number(end + r"KE/grain = (\S+) J", log),
        ke_rest=logs.number(end + r"rest threshold (\S+) J", log),
        collapse_time=logs.number(end + r"collapse time = (\S+) s", log),
        params=logs.contact_params(log, "DEM3D"), published=published_runout_range(aspect),
        log=logs.lines(log, "DEM3D "), **res)


def main(argv=None) -> int:
    p = cli.scene_parser(__doc__, 2024, dict(
        aspect=(2.0, "H0/L0"), width=(0.03, "L0, m"), d=(0.002, "mean grain diameter, m"),
        thickness=(4, "slab thickness in floor rows (1.2 d each)")), codes=CODES)
    a = cli.parse(p, argv)
    res = run(a.code, a.aspect, a.width, a.d, a.thickness, a.np_, a.out, a.seed, extra_vars=a.var)
    cli.print_result(res, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
