#!/usr/bin/env python3
"""High-speed impact of a large sphere into a settled 3D granular bed, run with LAMMPS
(input_decks/impact/dem_3d.lmp), LIGGGHTS (liggghts_3d.in, the twin deck) or the hybrid twin
(dem_3d.lmp with input_decks/impact/hybrid_3d.lmp: fix hybrid/mpm, adaptive zones).

Writes the initial grains (floor, a loose lattice to pour, the parked projectile), settles the bed
(prep stage, <out>/bed.data; --bed shoots into one settled before) and shoots into it. Measures the
bed surface and packing, the penetration depth against Uehara et al.'s law, the stopping time and
the Katsuragi-Durian drag fit (the method: tools/README.md, "dem_impact.py").

    tools/dem_impact.py --code lammps   --np 2 --out /tmp/imp_lmp
    tools/dem_impact.py --code liggghts --np 2 --out /tmp/imp_lig --bed /tmp/imp_lmp/bed.data
    tools/dem_impact.py --code hybrid   --np 1 --out /tmp/imp_hyb --bed /tmp/imp_lmp/bed.data
    # the reduced scene of the test:
    tools/dem_impact.py --code lammps --width 12 --depth 0.024 --dp 0.012 --speed 4 --out DIR
"""
from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hgtools import cli, logs
from hgtools.bed import box_packing, surface_near_axis
from hgtools.grains import FLOOR_SPACING, LATTICE_SPACING, grains_needed, jittered, max_overlap, pour_margin, \
    read_dump, write_spheres
from hgtools.impact import projectile_record
from hgtools.laws import G, uehara_depth
from hgtools.runner import CODES, Forms, workdir

FORMS = Forms("impact")


def write_data(path: Path, width_rows: int, depth: float, d: float, dp: float, seed: int,
               rho: float = 2500.0, rhop: float = 2500.0) -> dict:
    """Writes the data file (atom_style sphere: id type diameter density x y z) every form reads:
    the frozen floor, the grains to pour and the parked projectile (tools/README.md, "dem_impact.py")."""
    rng = np.random.default_rng(seed)
    fs = FLOOR_SPACING * d
    width = width_rows * fs
    f = (np.arange(width_rows) + 0.5) * fs
    FX, FY = np.meshgrid(f, f, indexing="ij")
    floor = np.column_stack([FX.ravel(), FY.ravel(), np.full(FX.size, -0.5 * d)])
    margin = pour_margin(d)
    n = int(math.floor((width - 2 * margin) / (LATTICE_SPACING * d))) + 1
    xs = margin + np.arange(n) * ((width - 2 * margin) / (n - 1))
    need = grains_needed(width * width * depth, d)
    zs = 0.6 * d + np.arange(int(math.ceil(need / (n * n)))) * LATTICE_SPACING * d
    X, Y, Z = np.meshgrid(xs, xs, zs, indexing="ij")
    grains, diam = jittered(rng, np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]), d)
    zp = zs[-1] + 0.6 * d + 0.5 * d + 0.5 * dp
    ztop = zp + 0.5 * dp + 0.5 * d
    ids = write_spheres(path, "Impact bed grains and projectile (tools/dem_impact.py)",
                        ((0.0, width), (0.0, width), (-1.5 * d, ztop)),
                        [("grains", 1, diam, rho, grains), ("floor", 2, d, rho, floor),
                         ("projectile", 3, dp, rhop, [[0.5 * width, 0.5 * width, zp]])], types=4)
    k = ids["projectile"][0]
    return dict(width=width, ztop=ztop, poured=len(grains), floor=len(floor), projectile_id=k)


@dataclass
class ImpactResult:
    code: str
    width: float
    depth_bed: float
    d: float
    dp: float
    rhop: float
    v0: float
    mu: float
    grains: int                 # grains in the settled bed
    packing: float              # bed packing fraction (bulk)
    surface: float              # bed surface z_s under the impact, m
    penetration: float          # final depth of the projectile's bottom below z_s, m
    max_depth: float            # largest depth reached, m
    stop_time: float            # s, first contact to -vz < vrest v0
    end_time: float             # s after the launch, when the run stopped
    at_rest: bool
    uehara: float               # Uehara et al. depth, m
    froude: float               # v0^2 / (g dp)
    drag_k: float               # Katsuragi-Durian k, N/m
    drag_d1: float              # Katsuragi-Durian d1, m
    drag_r2: float              # R^2 of that fit on the depth bins
    peak_decel: float           # largest deceleration of the projectile (bed force / m_p), m/s^2
    ke0: float                  # projectile kinetic energy at the launch, J
    proj_energy_gain: float     # max over the records of E_p(t) - E_p(0), J (E_p = KE + m g z)
    mobile_energy_gain: float   # max of E_mobile(t) - E_mobile(0), J
    atoms_launch: int
    atoms_end: int
    max_overlap_initial: float  # largest overlap / d in the settled bed
    max_overlap_final: float
    overlap_expected: float     # the deck's estimate for a grain hit at v0
    wall_time: float            # s, the impact stage (stiffening, relaxation, impact)
    prep_wall_time: float = 0.0  # s, the settling stage (0 when the bed was given)
    bed: str = ""               # the settled bed's data file
    mass_balance: float = float("nan")   # hybrid: max |M(t) - M(0)| / M(0) of the fix's total mass
    hybrid_points: int = 0      # hybrid: most material points at a record
    hybrid_cells: int = 0       # hybrid: most continuum + hybrid cells at a record
    params: dict = field(default_factory=dict)
    history: list = field(default_factory=list)   # [t, depth, v, decel] sampled
    drag_bins: list = field(default_factory=list)
    log: str = ""

    @property
    def ratio(self) -> float:
        """Measured depth / Uehara's."""
        return self.penetration / self.uehara

    def summary(self) -> str:
        return (f"{self.code}: box {self.width:.4g} m, bed {self.depth_bed:.4g} m, {self.grains} grains "
                f"(phi {self.packing:.3f}), dp = {self.dp:g} m, rho_p = {self.rhop:g}, v0 = {self.v0:g} m/s "
                f"(Fr = {self.froude:.0f}), wall time {self.wall_time:.1f} s (+ settling {self.prep_wall_time:.1f} s)\n"
                f"  penetration {self.penetration * 1e3:.2f} mm = {self.penetration / self.d:.2f} d "
                f"(max {self.max_depth * 1e3:.2f} mm), stopping time {self.stop_time * 1e3:.2f} ms, "
                f"{'at rest' if self.at_rest else 'NOT at rest'} at {self.end_time * 1e3:.1f} ms\n"
                f"  Uehara et al. (mu = {self.mu:g}): {self.uehara * 1e3:.2f} mm; measured/law = {self.ratio:.3f}\n"
                f"  Katsuragi-Durian fit: k = {self.drag_k:.4g} N/m, d1 = {self.drag_d1 * 1e3:.3g} mm, "
                f"R^2 = {self.drag_r2:.3f}; peak deceleration {self.peak_decel:.4g} m/s^2 "
                f"({self.peak_decel / G:.0f} g)\n"
                f"  energy: projectile KE0 {self.ke0:.4g} J, largest gain of the projectile's energy "
                f"{self.proj_energy_gain:.3g} J, of all mobile {self.mobile_energy_gain:.3g} J; atoms "
                f"{self.atoms_launch} -> {self.atoms_end}; max overlap/d settled {self.max_overlap_initial:.4f}, "
                f"final {self.max_overlap_final:.4f} (estimate at v0 {self.overlap_expected:.4f})"
                + (f"\n  hybrid: mass balance {self.mass_balance:.2e}, up to {self.hybrid_points} material points in "
                   f"{self.hybrid_cells} continuum + hybrid cells" if self.code == "hybrid" else ""))


def analyse(out: Path, log: str, code: str, width: float, depth: float, d: float, dp: float,
            rhop: float, v0: float, mu: float, rho: float, wall: float) -> ImpactResult:
    initial = read_dump(out / "initial.dump")
    final = read_dump(out / "final.dump")
    mend = re.search(r"^IMPACT end: t = (\S+) s after the launch, projectile z = (\S+) m, speed (\S+) m/s "
                     r"\(rest below (\S+)\), atoms (\d+) \(at launch (\d+)\)", log, re.M)
    if not mend:
        raise RuntimeError(f"no 'IMPACT end' line in the log of {out}")
    mp = rhop * math.pi / 6 * dp ** 3
    zs = surface_near_axis(initial, width, d, dp)
    phi = box_packing(initial, width, d, zs)
    measures = projectile_record(logs.records(out / "traj.dat"), zs, dp, mp, d, float(mend.group(4)))  # traj.dat
    h = v0 ** 2 / (2 * G) + max(measures.pop("launch_gap"), 0.0)
    zp_end = float(final["z"][final["type"] == 3][0])
    params = logs.contact_params(log, "IMPACT")
    params["settling kn"] = logs.number(r"^IMPACT settling contact: kn = (\S+) N/m", log)
    balance, points, hcells = logs.hybrid_mass_lines(log) if code == "hybrid" else (float("nan"), 0, 0)
    return ImpactResult(
        code=code, width=width, depth_bed=depth, d=d, dp=dp, rhop=rhop, v0=v0, mu=mu,
        grains=int((initial["type"] == 1).sum()), packing=phi, surface=zs,
        penetration=zs - (zp_end - 0.5 * dp), end_time=float(mend.group(1)),
        at_rest=float(mend.group(3)) < float(mend.group(4)),
        uehara=uehara_depth(rhop, phi * rho, dp, h, mu), froude=v0 ** 2 / (G * dp),
        atoms_launch=int(mend.group(6)), atoms_end=int(mend.group(5)),
        max_overlap_initial=max_overlap(initial, d), max_overlap_final=max_overlap(final, d),
        overlap_expected=logs.number(r"^IMPACT timestep:.*expected largest overlap/d (\S+)", log),
        wall_time=wall, mass_balance=balance, hybrid_points=points, hybrid_cells=hcells, params=params,
        log=logs.lines(log, "IMPACT ", "HYBRID "), **measures)


def run(code: str = "lammps", width_rows: int = 25, depth: float = 0.036, d: float = 0.002,
        dp: float = 0.016, speed: float = 5.0, rhop: float = 2500.0, np_: int = 1,
        out: str | Path | None = None, seed: int = 2024, timeout: float = 1800,
        extra_vars: dict | None = None, hybrid_vars: dict | None = None,
        exe: str | None = None, bed: str | Path | None = None) -> ImpactResult:
    """Writes the data file, runs `code`'s deck and analyses the output. Two processes: the
    settled bed (prep stage, <out>/bed.data; the hybrid form settles it with stock LAMMPS,
    the same deck) unless `bed` names one already settled (from any code, same geometry and
    parameters), then the impact from it (hybrid: dem_3d.lmp + hybrid_3d.lmp coupled,
    hybrid_vars its extra variables). width_rows: the box side in floor rows (1.2 d each)."""
    out = workdir(out, f"dem_impact_{code}", ("final.dump", "initial.dump", "traj.dat"))
    extra = {k: str(v) for k, v in (extra_vars or {}).items()}
    rho = float(extra.get("rho", 2500.0))
    mu = float(extra.get("mu", 0.5))
    geo = write_data(out / "grains.data", width_rows, depth, d, dp, seed, rho=rho, rhop=rhop)
    variables = dict(data=out / "grains.data", out=out, width=f"{geo['width']:.9g}", depth=depth, d=d,
                     dp=dp, rhop=rhop, v0=speed, ztop=f"{geo['ztop']:.9g}", **extra)
    prep_wall = 0.0
    if bed is None:
        bed = out / "bed.data"
        bed.unlink(missing_ok=True)
        prep_code = "lammps" if code == "hybrid" else code
        done = FORMS.run(prep_code, dict(variables, prep=1, impact=0, bed=bed), out / "log.prep.txt", np_=np_,
                         exe=exe if code != "hybrid" else None, timeout=timeout)
        done.check("to settle the bed", bed)
        prep_wall = done.wall
    variables.update(prep=0, impact=1, bed=Path(bed).resolve())
    done = FORMS.run(code, variables, out / "log.txt", hybrid_vars, np_=np_, exe=exe, timeout=timeout)
    log = done.check("in the impact", out / "final.dump")
    res = analyse(out, log, code, geo["width"], depth, d, dp, rhop, speed, mu, rho, done.wall)
    res.prep_wall_time = prep_wall
    res.bed = str(bed)
    return res


def main(argv=None) -> int:
    p = cli.scene_parser(__doc__, 2024, dict(
        width=(25, "box side in floor rows (1.2 d each)"), depth=(0.036, "bed depth, m"),
        d=(0.002, "mean grain diameter, m"), dp=(0.016, "projectile diameter, m"),
        rhop=(2500.0, "projectile density, kg/m^3"), speed=(5.0, "impact speed v0, m/s"),
        bed=(None, "settled bed (bed.data of an earlier run, same sizes): skip the settling", str)),
        codes=CODES, var="deck variable (e, mu, knv, knfac, dtdiv, vrest, tmin, tmax, trec, ...)",
        hvar="variable of the hybrid twin (hcell, hevery, hadapt, hdepth, hband, hradius, ...)")
    a = cli.parse(p, argv)
    res = run(a.code, a.width, a.depth, a.d, a.dp, a.speed, a.rhop, a.np_, a.out, a.seed,
              extra_vars=a.var, hybrid_vars=a.hvar, bed=a.bed)
    cli.print_result(res, a.json, ratio=res.ratio)
    return 0


if __name__ == "__main__":
    sys.exit(main())
