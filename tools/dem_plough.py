#!/usr/bin/env python3
"""The quasi-3D plough: a rigid vertical blade inserted to depth h into a settled granular bed
(a slab, periodic in z) and dragged in x at constant speed V, in three forms sharing one parameter
set: LAMMPS (input_decks/plough/dem_3d.lmp), LIGGGHTS (liggghts_3d.in, the twin deck) and the
hybrid twin (dem_3d.lmp with hybrid_3d.lmp: fix hybrid/mpm, a discrete region moving with the blade).

Writes the data file (floor, blade, grains to pour), runs one form and measures the mean drag on
the blade over the steady part of the drag, compared with Rankine's passive earth pressure
(the method: tools/README.md, "dem_plough.py").

    tools/dem_plough.py --code lammps   --np 2 --out /tmp/pl_lmp
    tools/dem_plough.py --code liggghts --np 2 --out /tmp/pl_lig
    tools/dem_plough.py --code hybrid   --np 2 --out /tmp/pl_hyb
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hgtools import cli, logs
from hgtools.bed import slab_bed
from hgtools.grains import (FLOOR_SPACING, LATTICE_SPACING, jittered, max_overlap, pour_lattice, read_dump,
                            slab_floor, write_spheres)
from hgtools.laws import rankine_drag
from hgtools.runner import CODES, Forms, workdir

FORMS = Forms("plough")

PHI_BED = 27.0          # internal friction angle of the bed, degrees (spheres, mu = 0.5: 25-30)
BLADE_SPACING = 0.5     # blade sphere spacing in y and z, in d (no grain passes, nearly flat)
BLADE_DENSITY = 1000.0  # blade spheres are this much denser than grains (m_eff = grain mass)
XBLADE_D = 4.0          # blade start, x of its plane, in d from the back wall
WINDOW = (0.5, 1.0)     # the steady part: this fraction of the dragged distance (from, to)
HYBRID_ROWS = 9          # hybrid twin's slab thickness in floor rows (10.8 d: see hybrid_3d.lmp)
END_MARGIN = 3.0        # end wall this many (1 + topfac) h beyond the blade's final position


def geometry(depth: float, d: float, drag: float, topfac: float) -> dict:
    """Blade start and end-wall position: the passive wedge in front of a blade of height
    (1 + topfac) h reaches ~ 1.7 (1 + topfac) h ahead (slip plane at 45 - phi/2 degrees);
    the end wall stays END_MARGIN times that height beyond the blade's final position."""
    xblade = XBLADE_D * d
    length = xblade + drag + END_MARGIN * (1 + topfac) * depth + 4 * d
    return dict(xblade=xblade, length=length)


def write_data(path: Path, bedh: float, depth: float, d: float, length: float, xblade: float,
               thickness_d: int, topfac: float, seed: int, rho: float = 2500.0) -> dict:
    """Writes the data file (atom_style sphere: id type diameter density x y z) both decks read:
    the frozen floor, the blade above the bed and the grains to pour (tools/README.md, "dem_plough.py")."""
    rng = np.random.default_rng(seed)
    W = thickness_d * FLOOR_SPACING * d
    floor = slab_floor(length + 1.5 * d, thickness_d, d)      # inside the box, x < length + 2 d
    # blade
    sy = BLADE_SPACING * d
    nyb = int(math.ceil(((1 + topfac) * depth - d) / sy)) + 1
    nzb = max(1, int(round(W / sy)))
    by = bedh + d + np.arange(nyb) * sy
    bz = (np.arange(nzb) + 0.5) * W / nzb
    BY, BZ = np.meshgrid(by, bz, indexing="ij")
    blade = np.column_stack([np.full(BY.size, xblade), BY.ravel(), BZ.ravel()])
    # grains: the column's loose lattice over the whole bed
    s = LATTICE_SPACING * d
    xs, zs, margin, need = pour_lattice(length, W, d, length * bedh * W)
    clear = 0.5 * d + margin                     # centre distance that no grain may come within
    free_x = np.abs(xs - xblade) >= clear
    sites = []
    layer = 0
    while len(sites) < need:
        y = 0.6 * d + layer * s
        row = xs if y < bedh + d - clear else xs[free_x]
        sites.extend((x, y, z) for x in row for z in zs)
        layer += 1
    grains, diam = jittered(rng, np.array(sites[:need]), d)
    grains[:, 2] %= W
    ytop = max(grains[:, 1].max(), by[-1]) + 4 * d
    write_spheres(path, "Quasi-3D plough: grains, floor, blade (tools/dem_plough.py)",
                  ((-2 * d, length + 2 * d), (-1.5 * d, ytop), (0.0, W)),
                  [("grains", 1, diam, rho, grains), ("floor", 2, d, rho, floor),
                   ("blade", 3, d, BLADE_DENSITY * rho, blade)], types=5)
    return dict(thickness=W, poured=len(grains), floor=len(floor), blade=len(blade), ytop=ytop)


def steady_drag(drag: np.ndarray, x0: float, dist: float, window=WINDOW, nblocks: int = 4) -> dict:
    """Mean drag -F_x over the window of blade displacement, the standard deviation of the
    tave-averages, and the spread of its nblocks block means (a measure of how steady it is)."""
    disp = drag[:, 1] - x0
    sel = (disp >= window[0] * dist) & (disp <= window[1] * dist)
    f = -drag[sel, 2]
    if len(f) < nblocks:
        raise RuntimeError(f"only {len(f)} drag records in the window {window} of {dist} m")
    blocks = [float(b.mean()) for b in np.array_split(f, nblocks)]
    return dict(drag=float(f.mean()), drag_std=float(f.std()), drag_blocks=blocks,
                drag_block_spread=float(np.std(blocks) / max(abs(f.mean()), 1e-300)),
                lift=float(-drag[sel, 3].mean()))


@dataclass
class PloughResult:
    code: str
    bedh: float
    depth: float
    d: float
    speed: float
    dragged: float               # distance dragged, m
    thickness: float             # slab thickness W, m
    grains: int                  # after trimming
    mass: float                  # grains' mass after trimming, kg
    mass_end: float              # grains' (carried) mass at the end, kg (hybrid: without the points)
    packing: float               # settled bed
    surface: float               # settled bed's mean surface height, m
    depth_actual: float          # surface - blade's lower edge, m
    blade_top: float             # blade's top edge above the surface after insertion, m
    drag: float                  # mean drag over the window, N
    drag_std: float              # std of the tave-averages in the window, N
    drag_blocks: list
    drag_block_spread: float
    lift: float
    rankine: float               # 1/2 K_p rho_b g h^2 W, N (h = depth_actual)
    max_overlap: float           # largest overlap / d, settled bed (grains and floor)
    wall_time: float
    params: dict = field(default_factory=dict)
    hybrid: dict = field(default_factory=dict)
    curve: list = field(default_factory=list)    # (displacement, drag) per tave
    log: str = ""

    @property
    def ratio(self) -> float:
        return self.drag / self.rankine

    def summary(self) -> str:
        s = (f"{self.code}: plough H = {self.bedh:g} m, h = {self.depth:g} m (actual {self.depth_actual:.4g}), "
             f"W = {self.thickness:.4g} m, V = {self.speed:g} m/s, {self.grains} grains, wall time {self.wall_time:.1f} s\n"
             f"  drag {self.drag:.4g} N (std of {len(self.curve)} records {self.drag_std:.3g} N, block means "
             f"{', '.join(f'{b:.4g}' for b in self.drag_blocks)}), lift {self.lift:.3g} N\n"
             f"  Rankine 1/2 K_p rho_b g h^2 W = {self.rankine:.4g} N (phi {PHI_BED:g} deg, packing "
             f"{self.packing:.3f}): drag / Rankine = {self.ratio:.3f}; max overlap/d {self.max_overlap:.4f}")
        if self.hybrid:
            s += "\n  hybrid: " + ", ".join(f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}"
                                           for k, v in self.hybrid.items())
        return s


def run(code: str = "lammps", depth: float = 0.012, bedh: float | None = None, d: float = 0.002,
        drag: float | None = None, speed: float = 0.1, topfac: float = 0.25, thickness_d: int | None = None,
        np_: int = 1, out: str | Path | None = None, seed: int = 2024, timeout: float = 900,
        extra_vars: dict | None = None, hybrid_vars: dict | None = None, exe: str | None = None) -> PloughResult:
    """Writes the data file, runs one form of the scene and analyses it. bedh defaults to 2 h,
    drag to 3 h; thickness_d: slab thickness W in floor rows (W = thickness_d * 1.2 d; default
    HYBRID_ROWS for the hybrid twin, whose continuum needs a thick slab, else 4, ~5 d).
    extra_vars: further deck variables (rho, e, mu, knfac, ..., zwall); hybrid_vars: variables
    of hybrid_3d.lmp (hcell, hdepth, ...). The hybrid twin always runs with zwall 1."""
    bedh = bedh if bedh is not None else 2 * depth
    if thickness_d is None:
        thickness_d = HYBRID_ROWS if code == "hybrid" else 4
    drag = drag if drag is not None else 3 * depth
    out = workdir(out, f"plough_{code}", ("final.dump", "settled.dump", "inserted.dump", "drag.dat"))
    geo = geometry(depth, d, drag, topfac)
    data = write_data(out / "grains.data", bedh, depth, d, geo["length"], geo["xblade"], thickness_d,
                      topfac, seed)
    variables = dict(data=out / "grains.data", out=out, bedh=bedh, depth=depth, d=d,
                     xblade=f"{geo['xblade']:.9g}", length=f"{geo['length']:.9g}", speed=speed,
                     drag=f"{drag:.9g}", **(extra_vars or {}))
    done = FORMS.run(code, variables, out / "log.txt", {"zwall": 1, **(hybrid_vars or {})}, np_=np_, exe=exe,
                     timeout=timeout, threads=1)
    log = done.check("in the drag", out / "final.dump", marker="PLOUGH drag end")
    settled = read_dump(out / "settled.dump")
    inserted = read_dump(out / "inserted.dump")
    bed = slab_bed(settled, bedh, geo["length"], d, data["thickness"])
    bl = inserted["type"] == 3
    lower_edge = float((inserted["y"][bl] - inserted["radius"][bl]).min())
    depth_actual = bed["surface"] - lower_edge
    x0 = float(inserted["x"][bl].mean())
    rec = logs.records(out / "drag.dat")    # fix ave/time: step, x_blade, F_x, F_y
    steady = steady_drag(rec, x0, drag)
    rho = float((extra_vars or {}).get("rho", 2500))
    rankine = rankine_drag(bed["packing"] * rho, depth_actual, PHI_BED) * data["thickness"]
    gm = (settled["type"] == 1) | (settled["type"] == 2)
    overlap = max_overlap({k: v[gm] for k, v in settled.items()}, d, data["thickness"])
    return PloughResult(
        code=code, bedh=bedh, depth=depth, d=d, speed=speed, dragged=drag, thickness=data["thickness"],
        grains=int(logs.number(r"^PLOUGH settled bed: (\d+) grains", log)),
        mass=logs.number(r"^PLOUGH settled bed:.*mass (\S+) kg", log),
        mass_end=logs.number(r"^PLOUGH drag end:.*mass (\S+) kg", log),
        packing=bed["packing"], surface=bed["surface"], depth_actual=depth_actual,
        blade_top=float((inserted["y"][bl] + inserted["radius"][bl]).max()) - bed["surface"],
        max_overlap=overlap, wall_time=done.wall, params=logs.contact_params(log, "PLOUGH"),
        hybrid=logs.hybrid_totals(log) if code == "hybrid" else {}, rankine=rankine,
        curve=[(float(a - x0), float(-b)) for a, b in zip(rec[:, 1], rec[:, 2])],
        log=logs.lines(log, "PLOUGH "), **steady)


def main(argv=None) -> int:
    p = cli.scene_parser(__doc__, 2024, dict(
        depth=(0.012, "h, m"), bedh=(None, "H, bed height, m (default 2 h)"), d=(0.002, "mean grain diameter, m"),
        drag=(None, "dragged distance, m (default 3 h)"), speed=(0.1, "V, m/s"),
        topfac=(0.25, "blade top edge above the bed, in h"),
        thickness=(None, f"slab thickness in floor rows (1.2 d each; default 4, hybrid {HYBRID_ROWS})", int)),
        codes=CODES, hvar="hybrid_3d.lmp variable (with --code hybrid)")
    a = cli.parse(p, argv)
    res = run(a.code, a.depth, a.bedh, a.d, a.drag, a.speed, a.topfac, a.thickness, a.np_, a.out, a.seed,
              extra_vars=a.var, hybrid_vars=a.hvar)
    cli.print_result(res, a.json, ratio=res.ratio)
    return 0


if __name__ == "__main__":
    sys.exit(main())
