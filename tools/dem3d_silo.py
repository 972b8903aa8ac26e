#!/usr/bin/env python3
"""Discharge of a 3D flat-bottomed silo of square cross-section through a circular orifice
(docs/design.md sections 3 and 6), in three forms sharing one parameter set:

    --code lammps    input_decks/silo/dem_3d.lmp with Debian's stock LAMMPS (`lmp`)
    --code liggghts  input_decks/silo/liggghts_3d.in with LIGGGHTS 3.8 (`liggghts`)
    --code hybrid    dem_3d.lmp + input_decks/silo/hybrid_3d.lmp (fix hybrid/mpm, adaptive
                     zones) through tools/hybrid_launch.py (lmp_hybrid + mpm_solver)
    --code hybrid_liggghts  liggghts_3d.in + input_decks/silo/hybrid_3d.liggghts (the same coupling
                     with LIGGGHTS as the DEM host: hybrid_launch.py --host liggghts)

Prepares the settled silo with `--prep-code` (default LAMMPS; cached in $HYBRID_CACHE/dem3d_silo/),
discharges it with `--code`, and measures the steady rate of the discharged mass against the 3D
Beverloo law (the method: tools/README.md, "dem3d_silo.py").

    tools/dem3d_silo.py --code lammps   --np 2 --out /tmp/s3_lmp
    tools/dem3d_silo.py --code liggghts --np 2 --out /tmp/s3_lig
    tools/dem3d_silo.py --code hybrid   --np 2 --out /tmp/s3_hyb --hvar houtlet=0.012
"""
from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hgtools import bed, cli, logs
from hgtools.bed import PACKING_MARGIN, floor_with_hole
from hgtools.cache import Settled
from hgtools.discharge import DISCHARGE_STAGE, Discharge, measure
from hgtools.grains import (FLOOR_SPACING, LATTICE_SPACING, covered_fraction, grains_needed, jittered, max_overlap,
                            pour_margin, read_data, write_spheres)
from hgtools.laws import BEVERLOO_C3D, BEVERLOO_K, G, beverloo_3d
from hgtools.runner import CODES, HYBRID_CODES, Forms, workdir

FORMS = Forms("silo", hybrid_liggghts="hybrid_3d.liggghts")
DEFAULTS = dict(width=0.03, height=0.04, orifice=0.012, d=0.002, rho=2500.0, tout=0.01)


def box_bottom(height: float, d: float, tout: float) -> float:
    """Lowest y of the box: a grain deleted once its centre is below ysink = -3 d must not leave
    the box within two deletion intervals, falling from the top of the fill (as dem_2d.lmp)."""
    return -3 * d - 2 * tout * math.sqrt(2 * G * (height + d)) - 2 * d


def write_data(path: Path, width: float, height: float, orifice: float, d: float, seed: int,
               rho: float = 2500.0, tout: float = 0.01) -> dict:
    """Writes the initial data file both decks read (atom_style sphere: id type diameter density
    x y z): the floor with the orifice left out and the grains to pour (tools/README.md, "dem3d_silo.py")."""
    rng = np.random.default_rng(seed)
    floor, spacing, d_eff = floor_with_hole(width, orifice, d)
    margin = pour_margin(d)
    xs = np.arange(margin, width - margin + 1e-12, LATTICE_SPACING * d)
    need = grains_needed(width * width * height, d)
    ys = 0.6 * d + np.arange(int(math.ceil(need / len(xs) ** 2))) * LATTICE_SPACING * d
    X, Y, Z = np.meshgrid(xs, ys, xs, indexing="ij")
    grains, diam = jittered(rng, np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]), d)
    ytop = ys[-1] + 4 * d
    ybot = box_bottom(height, d, tout)
    floor_xyz = np.column_stack([floor[:, 0], np.full(len(floor), -0.5 * d), floor[:, 1]])
    write_spheres(path, "3D silo grains (tools/dem3d_silo.py)",
                  ((-d, width + d), (ybot, ytop), (-d, width + d)),
                  [("grains", 1, diam, rho, grains), ("floor", 2, d, rho, floor_xyz)], types=3)
    return dict(poured=len(grains), floor=len(floor), floor_spacing=spacing, orifice_eff=d_eff,
                ytop=ytop, ybot=ybot)


def packing_fraction(data: dict, width: float, d: float, margin: float = PACKING_MARGIN,
                     voxel: float | None = None) -> tuple[float, float]:
    """(volume fraction, fill height) of the settled grains (type 1): the spheres' volume in the
    box margin*d from the side walls, the floor (y = 0) and the free surface (max y + r),
    rasterised on voxels of d/10."""
    g = data["type"] == 1
    r = data["radius"][g]
    top = float((data["y"][g] + r).max())
    return covered_fraction(np.column_stack([data["x"][g], data["y"][g], data["z"][g]]), r, [margin * d] * 3,
                            [width - margin * d, top - margin * d, width - margin * d], voxel or d / 10), top


@dataclass(kw_only=True)
class Silo3dResult(Discharge):
    code: str
    orifice_eff: float             # inscribed diameter of the lattice hole, m
    floor_mass: float              # mass of the frozen floor spheres (type 2), kg
    prep_code: str
    params: dict = field(default_factory=dict)
    outlet = property(lambda self: self.orifice_eff)

    def summary(self) -> str:
        return (f"{self.code}: 3D silo W = {self.width:g} m, H = {self.height:g} m, D = {self.orifice:g} m "
                f"(inscribed {self.orifice_eff:.4g} m, D/d = {self.orifice_eff / self.d:.3g}), d = {self.d:g} m: "
                f"{self.grains} grains, {self.mass0:.4g} kg, packing fraction {self.packing:.4f}\n"
                + self.times_line(f" ({self.prep_code})") + self.rate_line("kg/s") +
                f"  3D Beverloo C = {BEVERLOO_C3D:g}, k = {BEVERLOO_K:g}: {self.beverloo:.4g} kg/s; "
                f"measured/Beverloo = {self.ratio:.3f}"
                f"{'' if self.walls_far else ' (silo narrower than W > D + 30 d)'}\n"
                + self.balance_text() + f"{self.settled_below} grains below the lid level after settling; "
                f"max overlap/d settled {self.max_overlap_initial:.4f}")


SETTLED_RE = re.compile(r"^DEM3D settled: t = (\S+) s, grains (\d+), mass (\S+) kg \(after trimming (\S+)\), "
                        r"below the lid level (\d+)", re.M)


def prepare(width: float, height: float, orifice: float, d: float, seed: int, extra: dict, np_: int,
            prep_code: str = "lammps", use_cache: bool = True, cache_dir: str | Path | None = None,
            work: Path | None = None, exe: str | None = None, timeout: float = 1800) -> tuple[Path, dict, bool]:
    """The settled silo (data file) and its preparation record, from the cache or prepared
    now with `prep_code`. The orifice is part of the key (it is in the floor), and so are this
    driver and hgtools/bed.py (they write the initial grains), and the deck before its discharge
    stage."""
    prep_extra = {k: v for k, v in extra.items() if k not in ("tdis", "fstop")}
    cache = Settled.entry("dem3d_silo", f"w{width:g}_h{height:g}_D{orifice:g}_d{d:g}_s{seed}_{prep_code}",
                          dict(w=width, h=height, D=orifice, d=d, seed=seed, code=prep_code, np=np_, **prep_extra),
                          ((FORMS.deck(prep_code), DISCHARGE_STAGE), Path(__file__), Path(bed.__file__)), "settled.data",
                          cache_dir)
    if use_cache and cache.cached(with_info=True):
        return cache.path, cache.info(), False
    work = Path(work).resolve() if work else cache.path.parent
    work.mkdir(parents=True, exist_ok=True)
    geo = write_data(work / "grains.data", width, height, orifice, d, seed, float(extra.get("rho", DEFAULTS["rho"])),
                     float(extra.get("tout", DEFAULTS["tout"])))
    target = work / "settled.data"
    target.unlink(missing_ok=True)
    done = FORMS.run(prep_code, dict(data=work / "grains.data", out=work, settled=target, prep=1, discharge=0,
                                     width=width, height=height, orifice=orifice, d=d, **extra),
                     work / "log.prep.txt", np_=np_, exe=exe, timeout=timeout)
    m = done.match(f"to prepare the silo with {prep_code}", SETTLED_RE, target)
    info = dict(settle_time=float(m.group(1)), grains=int(m.group(2)), mass=float(m.group(3)),
                trimmed_mass=float(m.group(4)), below=int(m.group(5)), wall_time=done.wall, code=prep_code, **geo)
    if not use_cache:
        return target, info, True
    cache.store(target, info)
    return cache.path, info, True


def run(code: str = "lammps", width: float = DEFAULTS["width"], height: float = DEFAULTS["height"],
        orifice: float = DEFAULTS["orifice"], d: float = DEFAULTS["d"], np_: int = 1,
        out: str | Path | None = None, seed: int = 2024, prep_code: str = "lammps", use_cache: bool = True,
        cache_dir: str | Path | None = None, tdis: float = 1.0, fstop: float = 0.9, timeout: float = 1800,
        extra_vars: dict | None = None, hybrid_vars: dict | None = None, exe: str | None = None,
        prep_np: int | None = None) -> Silo3dResult:
    """Prepares (or takes from the cache) the settled silo with `prep_code`, discharges it with
    `code` and returns the measured result. extra_vars: further shared deck variables (rho, e,
    mu, knfac, dtdiv, ketol, tout); hybrid_vars: variables of hybrid_3d.lmp (code 'hybrid').
    exe: the program of `code` (lammps, liggghts; default from PATH). prep_np: ranks of the
    preparation (default np_)."""
    extra = {k: str(v) for k, v in (extra_vars or {}).items()}
    out = workdir(out, f"dem3d_silo_{code}", ("discharge.dat",))
    settled, info, prepared = prepare(width, height, orifice, d, seed, extra, prep_np or np_, prep_code, use_cache,
                                      cache_dir, None if use_cache else out / "prep",
                                      exe if prep_code == code else None, timeout)
    variables = dict(out=out, settled=settled, prep=0, discharge=1, width=width, height=height,
                     orifice=orifice, d=d, tdis=tdis, fstop=fstop, **extra)
    done = FORMS.run(code, variables, out / "log.txt", hybrid_vars, np_=np_, exe=exe, timeout=timeout)
    text = done.check(f"in the {code} discharge", out / "discharge.dat", marker="DEM3D end:")
    mo = re.search(r"^DEM3D open: step \S+, grains (\d+), mass (\S+) kg", text, re.M)
    n0, mass0 = int(mo.group(1)), float(mo.group(2))
    figures, (n_in, n_fall, n_del, n_all) = measure(out / "discharge.dat", mass0)
    if code not in HYBRID_CODES:
        lost = int(max(np.max(n0 - n_all - n_del), np.max(np.abs(n_all - n_in - n_fall)),
                       round(logs.number(r"^DEM3D end:.* lost (\S+)", text))))
    else:  # grains become points and back: the counts do not balance (the fix's totals do)
        figures["mass_balance"], lost = float("nan"), -1
    settled_state = read_data(settled)
    phi, top = packing_fraction(settled_state, width, d)
    rho = float(extra.get("rho", DEFAULTS["rho"]))
    steps, loop_time = logs.loops(text)
    return Silo3dResult(
        code=code, width=width, height=height, orifice=orifice, orifice_eff=float(info["orifice_eff"]), d=d,
        rho=rho, grains=n0, mass0=mass0, packing=phi, fill_height=top,
        floor_mass=float(settled_state["mass"][settled_state["type"] == 2].sum()),
        beverloo=beverloo_3d(phi * rho, float(info["orifice_eff"]), d), lost=lost,
        settled_below=int(info["below"]), settled_mass=float(info["mass"]), trimmed_mass=float(info["trimmed_mass"]),
        settle_time=float(info["settle_time"]), max_overlap_initial=max_overlap(settled_state, d),
        prep_code=info["code"], prep_wall_time=float(info["wall_time"]), wall_time=done.wall, prepared=prepared,
        steps=steps, loop_time=loop_time, params=logs.contact_params(text, "DEM3D"), log=logs.lines(text, "DEM3D "),
        **figures)


def main(argv=None) -> int:
    p = cli.scene_parser(__doc__, 2024, dict(
        width=(DEFAULTS["width"], "silo width W, m"), height=(DEFAULTS["height"], "fill height H, m"),
        orifice=(DEFAULTS["orifice"], "orifice diameter D, m"), d=(DEFAULTS["d"], "mean grain diameter, m"),
        tdis=(1.0, "discharge time after the opening, s"), fstop=(0.9, "or stop once this mass fraction has left"),
        prep_np=(None, "MPI ranks of the preparation (default --np)", int)),
        codes=CODES, cache="silo (with --out: prepared in it)",
        var="shared deck variable (mu, e, knfac, dtdiv, ketol, rho, tout)",
        hvar="variable of hybrid_3d.lmp (hcell, hevery, hadapt, hdepth, hband, houtlet, ...)")
    p.add_argument("--prep-code", choices=("lammps", "liggghts"), default="lammps",
                   help="code that prepares the settled silo (default lammps)")
    a = cli.parse(p, argv)
    res = run(a.code, a.width, a.height, a.orifice, a.d, a.np_, a.out, a.seed, a.prep_code, not a.no_cache,
              a.cache_dir, a.tdis, a.fstop, extra_vars=a.var, hybrid_vars=a.hvar, prep_np=a.prep_np)
    cli.print_result(res, a.json, ratio=res.ratio, halves_spread=res.halves_spread)
    return 0


if __name__ == "__main__":
    sys.exit(main())
