#!/usr/bin/env python3
"""High-speed impact of a large sphere into a settled 3D granular bed, run with LAMMPS
(input_decks/impact/dem_3d.lmp), LIGGGHTS (liggghts_3d.in, the twin deck: same parameter
block, same contact law) or the hybrid twin (dem_3d.lmp with input_decks/impact/hybrid_3d.lmp:
fix hybrid/mpm with adaptive zones, through tools/hybrid_launch.py).

This driver writes the initial grains (a data file every form reads: the frozen floor, a loose
lattice of polydisperse spheres to pour, and the parked projectile; the writing reuses the
lattice constants of tools/dem3d_collapse.py), runs one code's deck, and reads the settled bed
(initial.dump), the projectile's trajectory (traj.dat) and the final state (final.dump).

Measures (documented choices):
  * bed surface z_s: the mean, over 2 d x 2 d columns whose centres lie within dp of the box
    axis, of the highest grain top (z + r) in each column, in the settled bed;
  * penetration depth: z_s minus the projectile's bottom (z_p - dp/2) at the end (at rest);
    the largest depth reached is also reported;
  * stopping time: from the first contact (the first record where the bed pushes on the
    projectile, fz_p + m_p g > 0) to the first record where its downward speed -vz_p falls
    below the deck's rest speed vrest v0 (the projectile mostly does not bounce back: it
    slows down to a creep; a rebound is caught too, since -vz_p crosses that value on the
    way);
  * deceleration history: the bed's force on the projectile F = fz_p + m_p g, fitted over the
    penetration (from the contact to the stop) with the Katsuragi-Durian form
    F = m_p g + k z + m_p v^2 / d1 (z the depth of the bottom below z_s, v = -vz_p), by least
    squares on the records binned in depth (the single records are contact noise);
  * the Uehara et al. (PRL 90, 194301, 2003) depth d = (0.14/mu) (rho_p/rho_b)^(1/2)
    dp^(2/3) H^(1/3) with H = h + d solved for d, h = v0^2/(2 g) + the launch gap (the fall
    height that gives v0), mu = the deck's friction coefficient (Uehara's mu is the tangent of
    the angle of repose; for frictional spheres without rolling resistance that is about
    0.4-0.5), rho_b = phi rho with phi the bed's packing fraction measured away from walls,
    floor and surface.

Two processes per run: the settling stage (prep; the hybrid form settles with stock LAMMPS and
the same deck) writes <out>/bed.data, then the impact stage shoots into it. --bed skips the
settling and shoots into a bed settled before (by any of the codes, same sizes and parameters):
that is how tests/test_dem_impact.py compares the three forms on one packing.

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
from hgtools.grains import FLOOR_SPACING, LATTICE_SPACING, grains_needed, jittered, max_overlap, pour_margin, \
    read_dump, write_spheres
from hgtools.runner import CODES, Forms, workdir

FORMS = Forms("impact")
G = 9.81
UEHARA_C = 0.14              # Uehara et al. 2003, d = (0.14/mu) (rho_p/rho_b)^(1/2) D^(2/3) H^(1/3)
SURFACE_BIN = 2.0            # surface columns, in d
PACKING_MARGIN = 3.0         # packing fraction measured this many d from walls, floor, surface


def write_data(path: Path, width_rows: int, depth: float, d: float, dp: float, seed: int,
               rho: float = 2500.0, rhop: float = 2500.0) -> dict:
    """Writes the data file (atom_style sphere: id type diameter density x y z) every form reads.
    Box: side width = width_rows * FLOOR_SPACING d in x and y (walls at 0 and width). Floor:
    frozen spheres of diameter d, square lattice of spacing FLOOR_SPACING d, centres at
    z = -d/2. Grains: diameters uniform in [0.9, 1.1] d on a cubic lattice of spacing about
    LATTICE_SPACING d (a whole number of sites across the box), offsets up to
    +-LATTICE_JITTER d, from z = 0.6 d up until 1.08 * PHI_EST * width^2 * depth of grain
    volume (8 % extra to trim, as tools/dem3d_collapse.py). Projectile (type 3): parked on the
    axis just below the box top, above the lattice. Type 4 is the LIGGGHTS wall material."""
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


def bed_surface(dump: dict, width: float, d: float, dp: float) -> float:
    """Mean over the SURFACE_BIN d columns within dp of the axis of the highest grain top."""
    g = dump["type"] == 1
    x, y, top = dump["x"][g], dump["y"][g], dump["z"][g] + dump["radius"][g]
    b = SURFACE_BIN * d
    ix = np.floor(x / b).astype(int)
    iy = np.floor(y / b).astype(int)
    c = 0.5 * width
    tops = []
    for i in range(ix.min(), ix.max() + 1):
        for j in range(iy.min(), iy.max() + 1):
            if math.hypot((i + 0.5) * b - c, (j + 0.5) * b - c) > dp:
                continue
            sel = (ix == i) & (iy == j)
            if sel.any():
                tops.append(top[sel].max())
    return float(np.mean(tops))


def packing_fraction(dump: dict, width: float, d: float, surface: float,
                     margin: float = PACKING_MARGIN) -> float:
    """Grain volume over box volume in the inner box margin d from the walls, the floor and the
    surface (grains counted by their centre: exact on average for a box >> d); the margin
    shrinks for a bed shallower than 4 margins."""
    margin = min(margin, 0.25 * surface / d)
    g = dump["type"] == 1
    x, y, z, r = dump["x"][g], dump["y"][g], dump["z"][g], dump["radius"][g]
    lo, hi, ztop = margin * d, width - margin * d, surface - margin * d
    sel = (x > lo) & (x < hi) & (y > lo) & (y < hi) & (z > margin * d) & (z < ztop)
    vol = (hi - lo) ** 2 * (ztop - margin * d)
    return float((4.0 / 3.0 * math.pi * r[sel] ** 3).sum() / vol)


def uehara_depth(rho_p: float, rho_b: float, dp: float, h: float, mu: float) -> float:
    """Solves d = (0.14/mu) (rho_p/rho_b)^(1/2) dp^(2/3) (h + d)^(1/3) for d (fixed point:
    the map is a contraction, its slope A/(3 (h+d)^(2/3)) < 1 for these sizes)."""
    a = UEHARA_C / mu * math.sqrt(rho_p / rho_b) * dp ** (2.0 / 3.0)
    dpen = a * h ** (1.0 / 3.0)
    for _ in range(200):
        dpen = a * (h + dpen) ** (1.0 / 3.0)
    return dpen


def fit_drag(depth: np.ndarray, v: np.ndarray, force: np.ndarray, mp: float, d: float,
             nbins: int = 20) -> dict:
    """Katsuragi-Durian F = m g + k z + m v^2/d1 by least squares on depth bins of the
    penetration records (the bins' mean z, v^2 and F). Returns k, d1, the fit's R^2 on the
    bins, and the binned curve."""
    sel = depth > 0
    z, v2, f = depth[sel], v[sel] ** 2, force[sel] - mp * G
    if len(z) < 2 * nbins:
        return dict(k=float("nan"), d1=float("nan"), r2=float("nan"), bins=[])
    edges = np.linspace(0.0, z.max(), nbins + 1)
    idx = np.clip(np.digitize(z, edges) - 1, 0, nbins - 1)
    zb, vb, fb = [], [], []
    for i in range(nbins):
        s = idx == i
        if s.sum() >= 3:
            zb.append(z[s].mean()), vb.append(v2[s].mean()), fb.append(f[s].mean())
    zb, vb, fb = map(np.asarray, (zb, vb, fb))
    a = np.column_stack([zb, mp * vb])
    coef, *_ = np.linalg.lstsq(a, fb, rcond=None)
    pred = a @ coef
    ss = float(((fb - fb.mean()) ** 2).sum())
    r2 = 1.0 - float(((fb - pred) ** 2).sum()) / ss if ss > 0 else float("nan")
    k, inv_d1 = float(coef[0]), float(coef[1])
    return dict(k=k, d1=(1.0 / inv_d1) if inv_d1 > 0 else float("inf"), r2=r2,
                bins=[[float(p), float(q), float(w) + mp * G] for p, q, w in zip(zb, np.sqrt(vb), fb)])


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
    tr = logs.records(out / "traj.dat")    # t, z_p, vz_p, fz_p, KE_p, E_mobile
    t, zp, vz, fz, kp, em = (tr[:, k] for k in range(6))
    mend = re.search(r"^IMPACT end: t = (\S+) s after the launch, projectile z = (\S+) m, speed (\S+) m/s "
                     r"\(rest below (\S+)\), atoms (\d+) \(at launch (\d+)\)", log, re.M)
    if not mend:
        raise RuntimeError(f"no 'IMPACT end' line in the log of {out}")
    mp = rhop * math.pi / 6 * dp ** 3
    zs = bed_surface(initial, width, d, dp)
    phi = packing_fraction(initial, width, d, zs)
    dep = zs - (zp - 0.5 * dp)
    bed_force = fz + mp * G
    touching = np.nonzero(bed_force > 1e-9 * mp * G)[0]
    i0 = int(touching[0]) if len(touching) else 0
    vstop = float(mend.group(4))
    up = np.nonzero((-vz < vstop) & (np.arange(len(t)) > i0))[0]
    i1 = int(up[0]) if len(up) else len(t) - 1
    fit = fit_drag(dep[i0:i1 + 1], -vz[i0:i1 + 1], bed_force[i0:i1 + 1], mp, d)
    gap = float(dep[0] * -1.0)      # launch gap: bottom above the surface (depth < 0)
    h = v0 ** 2 / (2 * G) + max(gap, 0.0)
    ep = kp + mp * G * zp
    pf = final["type"] == 3
    zp_end = float(final["z"][pf][0])
    step = max(1, len(t) // 400)
    hist = [[float(t[k]), float(dep[k]), float(-vz[k]), float(bed_force[k] / mp)] for k in range(0, len(t), step)]
    params = logs.contact_params(log, "IMPACT")
    params["settling kn"] = logs.number(r"^IMPACT settling contact: kn = (\S+) N/m", log)
    balance, points, hcells = float("nan"), 0, 0
    if code == "hybrid":
        rows = re.findall(r"^HYBRID mass (\S+) points (\S+) cells continuum (\S+) hybrid (\S+)", log, re.M)
        if rows:
            masses = [float(r[0]) for r in rows]
            balance = max(abs(m - masses[0]) for m in masses) / masses[0]
            points = int(max(float(r[1]) for r in rows))
            hcells = int(max(float(r[2]) + float(r[3]) for r in rows))
    lines = logs.lines(log, "IMPACT ", "HYBRID ")
    return ImpactResult(
        code=code, width=width, depth_bed=depth, d=d, dp=dp, rhop=rhop, v0=v0, mu=mu,
        grains=int((initial["type"] == 1).sum()), packing=phi, surface=zs,
        penetration=zs - (zp_end - 0.5 * dp), max_depth=float(dep.max()),
        stop_time=float(t[i1] - t[i0]), end_time=float(mend.group(1)),
        at_rest=float(mend.group(3)) < float(mend.group(4)),
        uehara=uehara_depth(rhop, phi * rho, dp, h, mu), froude=v0 ** 2 / (G * dp),
        drag_k=fit["k"], drag_d1=fit["d1"], drag_r2=fit["r2"], peak_decel=float(bed_force.max() / mp),
        ke0=float(kp[0]), proj_energy_gain=float((ep - ep[0]).max()),
        mobile_energy_gain=float((em - em[0]).max()),
        atoms_launch=int(mend.group(6)), atoms_end=int(mend.group(5)),
        max_overlap_initial=max_overlap(initial, d), max_overlap_final=max_overlap(final, d),
        overlap_expected=logs.number(r"^IMPACT timestep:.*expected largest overlap/d (\S+)", log),
        wall_time=wall, mass_balance=balance, hybrid_points=points, hybrid_cells=hcells, params=params, history=hist, drag_bins=fit["bins"],
        log=lines)


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
