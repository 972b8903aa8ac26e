#!/usr/bin/env python3
"""Calibrate the continuum from the grains (docs/design.md section 4.6, docs/calibration.md).

Short pure-DEM runs of one contact law in a periodic cell (input_decks/calibration/
simple_shear.lmp, Debian's `lmp`) measure what the continuum needs, and write a material file
that `fix hybrid/mpm ... material FILE` reads:

  1. prep: the grains are compressed isotropically to the pressure p0 = kn / kappa (2D) or
     kn / (kappa d) (3D) and come to rest: the packing fraction of the settled material;
  2. elastic: a small uniaxial strain of that packing, relaxed before and after; the change of
     stress gives the P-wave modulus M = lambda + 2G and lambda, so Young's modulus and
     Poisson's ratio of the packing (its wave speed is sqrt(M / rho_bulk));
  3. shear: pressure-controlled simple shear (Lees-Edwards) at several inertial numbers I; each
     gives the steady friction mu = tau / p (tau = |dev sigma| / sqrt 2, the continuum's own
     measure) and packing fraction phi. A least-squares fit of the mu(I) law
     mu = mu_s + (mu_2 - mu_s) / (I0 / I + 1) gives mu_s, mu_2 and I0; the Drucker-Prager
     angle is the one whose cone holds mu_s (2D plane strain: sin phi = mu_s; 3D through the
     compression meridian: sin phi = 3 mu_s / (2 sqrt 3 + mu_s)); the critical packing (below
     it the continuum carries no stress) is phi of the steady flow at the largest I calibrated.

Everything is dimensionless: lengths in d, stresses in p0, so one file serves every grain size
and stiffness of the law at that stiffness number. Results: OUT/calibration.json (every run,
the fits), OUT/calibration.md, OUT/mu_I.png, and the material file.

    tools/calibrate.py --dimension 2 --out runs/calib_2d --material input_decks/materials/disks_2d.toml
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from hgtools.grains import write_spheres
from hgtools.materials import material_path, read_material
from hgtools.runner import run_deck

REPO = Path(__file__).resolve().parent.parent
DECK = REPO / "input_decks" / "calibration" / "simple_shear.lmp"

# The reference grain of the runs (SI): results are made dimensionless with these.
D_REF, RHO_REF, P0_REF = 1.0e-3, 2500.0, 100.0
STEADY_FROM = 0.5            # the steady window: the second half of the shear strain
# A run whose mean pressure is this far from p0 had no steady dense flow at its I (past
# I ~ 0.3-0.5 a sheared cell at fixed pressure dilutes into a gas, whose pressure rises as it
# expands): it is reported and left out of the fits.
PRESSURE_TOLERANCE = 0.25
INERTIAL_DEFAULT = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3)


@dataclass
class ContactLaw:
    dimension: int = 2
    friction: float = 0.5             # Coulomb mu, grain-grain
    restitution: float = 0.5          # of a mean-size pair
    kt_over_kn: float = 2.0 / 7.0
    gammat_over_gamman: float = 0.5
    polydispersity: float = 0.1       # diameters uniform in [(1-p) d, (1+p) d]
    stiffness_number: float = 1000.0  # kappa = kn / p (2D), kn / (p d) (3D)
    pair: str = "gran/hooke/history"

    def deck_vars(self) -> dict:
        return {"dim": self.dimension, "mu": self.friction, "e": self.restitution, "ktkn": self.kt_over_kn,
                "gtgn": self.gammat_over_gamman, "poly": self.polydispersity, "kappa": self.stiffness_number,
                "d": D_REF, "rho": RHO_REF, "p0": P0_REF}

    @property
    def kn(self) -> float:
        return self.stiffness_number * P0_REF * (D_REF if self.dimension == 3 else 1.0)


@dataclass
class ShearPoint:
    target_inertial: float
    inertial: float          # measured over the steady window, gammadot d / sqrt(p / rho_s)
    mu: float                # tau / p, tau = |dev sigma| / sqrt(2)
    packing: float
    pressure: float          # p / p0
    mu_first_half: float     # of the steady window's first and second halves (steadiness)
    mu_second_half: float
    used: bool               # in the fits (its pressure held at p0)
    strain: float
    steps: int
    wall_s: float


@dataclass
class Calibration:
    law: ContactLaw
    grains: int
    packing: float = 0.0              # settled at p0 (prep)
    pwave_over_kn: float = 0.0        # M / kn (2D), M d / kn (3D)
    lambda_over_kn: float = 0.0
    youngs_over_kn: float = 0.0
    poisson: float = 0.0
    points: list = field(default_factory=list)
    mu_s: float = 0.0
    mu_2: float = 0.0
    I0: float = 0.0
    fit_rms: float = 0.0
    packing_slope: float = 0.0        # b in phi(I) = phi_0 - b I
    packing_intercept: float = 0.0
    critical_packing: float = 0.0
    friction_angle: float = 0.0
    wall_s: float = 0.0


# ----------------------------------------------------------------------------- running
def lammps(stage: str, law: ContactLaw, run_dir: Path, lmp: str, timeout: float, **extra) -> float:
    """Runs one stage of the calibration deck in run_dir; returns its wall time."""
    log = run_dir / f"{stage}.log"
    try:
        done = run_deck("lammps", DECK, {**law.deck_vars(), "stage": stage, "out": str(run_dir), **extra}, log,
                        exe=lmp, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise SystemExit(f"calibrate: the {stage} run in {run_dir} took more than {timeout:.0f} s "
                         f"(raise --timeout, or use fewer grains)")
    if done.proc.returncode != 0:
        tail = "\n".join((done.text() or done.proc.stdout + done.proc.stderr).splitlines()[-15:])
        raise SystemExit(f"calibrate: the {stage} run failed (exit {done.proc.returncode}), {log}:\n{tail}")
    return done.wall


def chunks(path: Path) -> np.ndarray:
    """Rows of a stage's chunk file: step, strain (or side), lx, ly, lz, pxx pyy pzz pxy pxz pyz, KE."""
    return np.loadtxt(path, ndmin=2)


def grain_volume(diameters: np.ndarray, dimension: int) -> float:
    return float(np.sum(np.pi / 4 * diameters ** 2) if dimension == 2 else np.sum(np.pi / 6 * diameters ** 3))


def write_grains(law: ContactLaw, n: int, seed: int, path: Path) -> float:
    """n grains on a loose lattice (spacing 1.5 d_max) with random diameters, in a periodic cell
    as near cubic as n allows; returns their total volume (area in 2D)."""
    rng = np.random.default_rng(seed)
    dim = law.dimension
    side = math.ceil(n ** (1.0 / dim) - 1e-9)
    spacing = 1.5 * (1 + law.polydispersity) * D_REF
    idx = np.array(np.unravel_index(np.arange(n), (side,) * dim)).T
    pos = (idx + 0.5) * spacing
    pos = np.hstack([pos, np.zeros((n, 3 - dim))])
    diam = D_REF * rng.uniform(1 - law.polydispersity, 1 + law.polydispersity, n)
    length = side * spacing
    box = ((0, length), (0, length), (0, length) if dim == 3 else (-0.5, 0.5))
    # 2D: the deck sets density/disc after reading (the data file's density is a sphere's)
    write_spheres(path, f"calibration grains, {dim}D, {n} grains", box, [("grains", 1, diam, RHO_REF, pos)], 1)
    return grain_volume(diam, dim)


# ----------------------------------------------------------------------------- measuring
def stress_measures(rows: np.ndarray, dimension: int) -> tuple[float, float]:
    """Mean pressure p = tr(sigma)/D and tau = |dev sigma| / sqrt(2) of the mean stress of rows
    (LAMMPS signs: compression positive, which leaves tau and p as they are)."""
    s = rows[:, 5:11].mean(axis=0)
    xx, yy, zz, xy, xz, yz = s
    if dimension == 2:
        p = 0.5 * (xx + yy)
        tau = math.sqrt(0.25 * (xx - yy) ** 2 + xy ** 2)
    else:
        p = (xx + yy + zz) / 3.0
        dev = np.array([[xx - p, xy, xz], [xy, yy - p, yz], [xz, yz, zz - p]])
        tau = math.sqrt(0.5 * float(np.sum(dev * dev)))
    return p, tau


def cell_volume(rows: np.ndarray, dimension: int) -> np.ndarray:
    return rows[:, 2] * rows[:, 3] * (rows[:, 4] if dimension == 3 else 1.0)


def prep(law: ContactLaw, n: int, seed: int, run_dir: Path, lmp: str, timeout: float) -> float:
    """Writes the loose grains, packs them at p0 (packed.restart); returns their total volume."""
    vgrains = write_grains(law, n, seed, run_dir / "grains.data")
    lammps("prep", law, run_dir, lmp, timeout, data=run_dir / "grains.data", vgrains=f"{vgrains:.12g}")
    return vgrains


def elastic(law: ContactLaw, vgrains: float, run_dir: Path, lmp: str, timeout: float, eps: float) -> dict:
    """P-wave modulus and lambda from the relaxed stress before and after a uniaxial strain eps."""
    lammps("elastic", law, run_dir, lmp, timeout, vgrains=f"{vgrains:.12g}", eps=eps)
    rows = chunks(run_dir / "elastic.chunks")
    before, after = rows[rows[:, 1] == 1][-10:], rows[rows[:, 1] == 2][-10:]
    s0, s1 = before[:, 5:11].mean(axis=0), after[:, 5:11].mean(axis=0)
    # virial stress of the current volume; LAMMPS's sign is compression positive, as is the strain
    m = (s1[1] - s0[1]) / eps
    lam = ((s1[0] - s0[0]) if law.dimension == 2 else 0.5 * (s1[0] - s0[0] + s1[2] - s0[2])) / eps
    g = 0.5 * (m - lam)
    if not (g > 0):
        raise SystemExit(f"calibrate: the elastic stage gave no shear stiffness (M = {m:.4g}, lambda = {lam:.4g}): "
                         f"the packing is not at rest or not jammed; see {run_dir / 'elastic.log'}")
    lam_eff = max(lam, 0.0)     # a negative lambda (nu < 0) is outside the continuum's range
    youngs = g * (3 * lam_eff + 2 * g) / (lam_eff + g)
    nu = lam_eff / (2 * (lam_eff + g))
    scale = law.kn / (D_REF if law.dimension == 3 else 1.0)
    return {"pwave_over_kn": m / scale, "lambda_over_kn": lam / scale, "youngs_over_kn": youngs / scale,
            "poisson": nu}


def shear(law: ContactLaw, vgrains: float, base: Path, inertial: float, strain: float, lmp: str,
          timeout: float) -> ShearPoint:
    run_dir = base / f"shear_I{inertial:g}"
    run_dir.mkdir(parents=True, exist_ok=True)
    shutil.copy(base / "packed.restart", run_dir / "packed.restart")    # the deck reads it from its out
    chunk_file = run_dir / "shear.chunks"
    chunk_file.unlink(missing_ok=True)
    wall = lammps("shear", law, run_dir, lmp, timeout, vgrains=f"{vgrains:.12g}", inertial=inertial, strain=strain)
    rows = chunks(chunk_file)
    steady = rows[rows[:, 1] >= STEADY_FROM * rows[-1, 1]]
    halves = np.array_split(steady, 2)
    p, tau = stress_measures(steady, law.dimension)
    rate = inertial * math.sqrt(P0_REF / RHO_REF) / D_REF
    mu_halves = [stress_measures(h, law.dimension) for h in halves]
    return ShearPoint(
        target_inertial=inertial, inertial=rate * D_REF / math.sqrt(p / RHO_REF), mu=tau / p,
        packing=float(np.mean(vgrains / cell_volume(steady, law.dimension))), pressure=p / P0_REF,
        mu_first_half=mu_halves[0][1] / mu_halves[0][0], mu_second_half=mu_halves[1][1] / mu_halves[1][0],
        used=bool(abs(p / P0_REF - 1) <= PRESSURE_TOLERANCE), strain=float(rows[-1, 1]), steps=int(rows[-1, 0]), wall_s=wall)


# ----------------------------------------------------------------------------- fitting
def fit_mu_i(inertial: np.ndarray, mu: np.ndarray) -> tuple[float, float, float, float]:
    """Least squares of mu = mu_s + (mu_2 - mu_s) I / (I0 + I): linear in (mu_s, mu_2) for a given
    I0, so I0 is searched on a fine logarithmic grid. Returns mu_s, mu_2, I0, rms residual."""
    best = None
    for i0 in np.logspace(-3, 1, 801):
        f = inertial / (i0 + inertial)
        a = np.column_stack([1 - f, f])
        coef, *_ = np.linalg.lstsq(a, mu, rcond=None)
        rms = float(np.sqrt(np.mean((a @ coef - mu) ** 2)))
        if coef[1] > coef[0] > 0 and (best is None or rms < best[3]):
            best = (float(coef[0]), float(coef[1]), float(i0), rms)
    if best is None:
        raise SystemExit("calibrate: mu(I) does not rise with I over the runs; no mu(I) law fits them "
                         f"(I = {inertial.round(4).tolist()}, mu = {mu.round(4).tolist()})")
    return best


def drucker_prager_angle(mu_s: float, dimension: int) -> float:
    """The friction angle (degrees) of the continuum's Drucker-Prager cone that holds tau = mu_s p
    (docs/design.md section 4.3: |dev tau| <= alpha p with alpha = sqrt(2) sin phi in 2D and
    sqrt(2/3) 6 sin phi / (3 - sin phi) in 3D, tau = |dev| / sqrt 2)."""
    s = mu_s if dimension == 2 else 3 * mu_s / (2 * math.sqrt(3) + mu_s)
    if not s < 1:
        raise SystemExit(f"calibrate: mu_s = {mu_s:.4g} exceeds what a Drucker-Prager cone can hold in {dimension}D")
    return math.degrees(math.asin(s))


def calibrate(law: ContactLaw, out: Path, grains: int, inertial: tuple, strain: float, seed: int, lmp: str,
              jobs: int, timeout: float, eps_factor: float = 0.1) -> Calibration:
    out.mkdir(parents=True, exist_ok=True)
    (out / "prep.chunks").unlink(missing_ok=True)
    (out / "elastic.chunks").unlink(missing_ok=True)
    t0 = time.time()
    vgrains = prep(law, grains, seed, out, lmp, timeout)
    prep_rows = chunks(out / "prep.chunks")
    cal = Calibration(law=law, grains=grains)
    cal.packing = float(vgrains / cell_volume(prep_rows[-1:], law.dimension)[0])
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        el = pool.submit(elastic, law, vgrains, out, lmp, timeout, eps_factor / law.stiffness_number)
        # the slowest (lowest I) first, so that the pool ends together
        futures = [pool.submit(shear, law, vgrains, out, i, strain, lmp, timeout) for i in sorted(inertial)]
        points = [f.result() for f in futures]
        e = el.result()
    cal.pwave_over_kn, cal.lambda_over_kn = e["pwave_over_kn"], e["lambda_over_kn"]
    cal.youngs_over_kn, cal.poisson = e["youngs_over_kn"], e["poisson"]
    cal.points = points
    used = [p for p in points if p.used]
    if len(used) < 3:
        raise SystemExit(f"calibrate: only {len(used)} shear runs held the pressure at p0 (within "
                         f"{PRESSURE_TOLERANCE:.0%}); mu(I) needs three: choose smaller inertial numbers")
    i_meas = np.array([p.inertial for p in used])
    mu = np.array([p.mu for p in used])
    # rounded as the material file writes them, so that its friction angle is that of its mu_s
    cal.mu_s, cal.mu_2, cal.I0, cal.fit_rms = (round(v, 4) for v in fit_mu_i(i_meas, mu))
    slope, intercept = np.polyfit(i_meas, [p.packing for p in used], 1)
    cal.packing_slope, cal.packing_intercept = float(-slope), float(intercept)
    cal.critical_packing = float(intercept + slope * i_meas.max())
    cal.friction_angle = drucker_prager_angle(cal.mu_s, law.dimension)
    cal.wall_s = time.time() - t0
    return cal


# ----------------------------------------------------------------------------- writing
def describe_material(name: str) -> str:
    """One sentence naming a committed material (input_decks/materials/NAME.toml) and the constants
    it gives the continuum, for reports that say which calibration their runs used."""
    path = material_path(name)
    material = read_material(name)
    c = material["continuum"]
    unit = "kn" if material["material"]["dimension"] == 2 else "kn/d"
    return (f"the material calibrated from the grains, `{path.relative_to(REPO)}` (tools/calibrate.py: "
            f"Drucker-Prager {c['friction_angle']:.2f} degrees, E = {c['youngs_over_kn']:.3f} {unit}, "
            f"nu = {c['poisson']:.3f})")


def material_toml(cal: Calibration, name: str, command: str) -> str:
    law = cal.law
    pts = "\n".join(f"#   I = {p.inertial:.4f}: mu = {p.mu:.4f}, phi = {p.packing:.4f}" for p in cal.points if p.used)
    k_unit = "kn" if law.dimension == 2 else "kn / d"
    return f"""# Material calibrated from its grains by tools/calibrate.py (docs/calibration.md):
#   {command}
# {cal.grains} grains, periodic cell; packing at p = kn / kappa: phi = {cal.packing:.4f};
# P-wave modulus {cal.pwave_over_kn:.4f} {k_unit}, lambda {cal.lambda_over_kn:.4f} {k_unit};
# pressure-controlled simple shear, steady mu = tau / p and phi at each inertial number:
{pts}
# mu(I) fit rms {cal.fit_rms:.4f}; phi(I) = {cal.packing_intercept:.4f} - {cal.packing_slope:.4f} I.

[material]
name = "{name}"
dimension = {law.dimension}

[contact]
pair = "{law.pair}"
friction = {law.friction:.6g}
restitution = {law.restitution:.6g}
kt_over_kn = {law.kt_over_kn:.6g}
gammat_over_gamman = {law.gammat_over_gamman:.6g}
polydispersity = {law.polydispersity:.6g}
stiffness_number = {law.stiffness_number:.6g}

[continuum]
packing_fraction = {cal.packing:.4f}
critical_packing = {cal.critical_packing:.4f}
youngs_over_kn = {cal.youngs_over_kn:.4f}
poisson = {cal.poisson:.4f}
mu_s = {cal.mu_s:.4f}
mu_2 = {cal.mu_2:.4f}
I0 = {cal.I0:.4f}
friction_angle = {cal.friction_angle:.3f}
"""


def report(cal: Calibration, out: Path, name: str, command: str) -> None:
    (out / "calibration.json").write_text(json.dumps({"name": name, "command": command, **asdict(cal)}, indent=1))
    law = cal.law
    rows = "\n".join(
        f"| {p.target_inertial:g} | {p.inertial:.4f} | {p.mu:.4f} | {p.mu_first_half:.4f} / {p.mu_second_half:.4f} "
        f"| {p.packing:.4f} | {p.pressure:.3f}{'' if p.used else ' (left out: no steady dense flow)'} "
        f"| {p.strain:.2f} | {p.steps} | {p.wall_s:.0f} |" for p in cal.points)
    (out / "calibration.md").write_text(f"""# Calibration of `{name}`

`{command}`

Contact law: {law.dimension}D, `pair_style {law.pair}`, friction {law.friction:g}, restitution {law.restitution:g}
(mean-size pair), kt/kn {law.kt_over_kn:.4g}, gamma_t/gamma_n {law.gammat_over_gamman:g}, diameters within
±{law.polydispersity:g} d, stiffness number kappa = {law.stiffness_number:g}. {cal.grains} grains in a periodic cell;
wall time {cal.wall_s:.0f} s.

| target I | measured I | mu = tau/p | mu, steady window's halves | phi | p / p0 | strain | steps | wall s |
| --- | --- | --- | --- | --- | --- | --- | --- | --- |
{rows}

- mu(I) = mu_s + (mu_2 - mu_s) / (I0/I + 1): **mu_s = {cal.mu_s:.4f}, mu_2 = {cal.mu_2:.4f}, I0 = {cal.I0:.4f}**
  (rms {cal.fit_rms:.4f}); Drucker-Prager friction angle {cal.friction_angle:.2f} degrees.
- phi(I) = {cal.packing_intercept:.4f} - {cal.packing_slope:.4f} I; critical packing (phi at the largest I)
  {cal.critical_packing:.4f}; settled packing at p0 {cal.packing:.4f}.
- Elastic: M = {cal.pwave_over_kn:.4f}, lambda = {cal.lambda_over_kn:.4f}, E = {cal.youngs_over_kn:.4f}
  (in units of kn{'' if law.dimension == 2 else '/d'}), Poisson's ratio {cal.poisson:.4f}.
""")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    pts = [p for p in cal.points if p.used]
    i = np.array([p.inertial for p in pts])
    grid = np.logspace(math.log10(i.min() / 2), math.log10(i.max() * 2), 200)
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6))
    a.semilogx(i, [p.mu for p in pts], "o", label="DEM, simple shear")
    a.semilogx(grid, cal.mu_s + (cal.mu_2 - cal.mu_s) / (cal.I0 / grid + 1), "-", label="mu(I) fit")
    a.set_xlabel("inertial number I")
    a.set_ylabel("mu = tau / p")
    a.legend()
    b.semilogx(i, [p.packing for p in pts], "o")
    b.semilogx(grid, cal.packing_intercept - cal.packing_slope * grid, "-")
    b.set_xlabel("inertial number I")
    b.set_ylabel("packing fraction")
    fig.suptitle(name)
    fig.tight_layout()
    fig.savefig(out / "mu_I.png", dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    law = ContactLaw()
    p.add_argument("--dimension", type=int, choices=(2, 3), default=2)
    p.add_argument("--friction", type=float, default=law.friction, help="Coulomb friction of the contacts")
    p.add_argument("--restitution", type=float, default=law.restitution, help="of a mean-size pair")
    p.add_argument("--kt-over-kn", type=float, default=law.kt_over_kn)
    p.add_argument("--gt-over-gn", type=float, default=law.gammat_over_gamman, help="gamma_t / gamma_n")
    p.add_argument("--polydispersity", type=float, default=law.polydispersity,
                   help="diameters uniform in [(1-p) d, (1+p) d]")
    p.add_argument("--stiffness", type=float, default=None,
                   help="stiffness number kappa = kn/p (2D) or kn/(p d) (3D) (default 1000 in 2D, 500 in 3D)")
    p.add_argument("--grains", type=int, default=None, help="grains in the cell (default 1000 in 2D, 2000 in 3D)")
    p.add_argument("--inertial", default=",".join(map(str, INERTIAL_DEFAULT)), help="inertial numbers of the shear runs")
    p.add_argument("--strain", type=float, default=3.0, help="shear strain of each run (the second half is averaged)")
    p.add_argument("--seed", type=int, default=1234)
    p.add_argument("--name", default=None, help="material name (default from the law)")
    p.add_argument("--out", required=True, help="directory of the runs and the report")
    p.add_argument("--material", default=None, help="material file to write (default OUT/NAME.toml)")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="LAMMPS runs at once (one rank each)")
    p.add_argument("--lmp", default="lmp", help="LAMMPS executable")
    p.add_argument("--timeout", type=float, default=3600, help="seconds for any one LAMMPS run")
    a = p.parse_args(argv)
    if a.polydispersity < 0 or a.polydispersity >= 0.9:
        p.error("--polydispersity must be in [0, 0.9)")
    try:
        inertial = tuple(float(x) for x in a.inertial.split(","))
    except ValueError:
        p.error(f"--inertial takes numbers separated by commas, not {a.inertial!r}")
    if len(inertial) < 3 or min(inertial) <= 0:
        p.error("--inertial needs at least three positive inertial numbers (mu(I) has three constants)")
    if shutil.which(a.lmp) is None:
        p.error(f"LAMMPS '{a.lmp}' not found (Debian package lammps; tools/setup.sh installs it)")
    law = ContactLaw(dimension=a.dimension, friction=a.friction, restitution=a.restitution, kt_over_kn=a.kt_over_kn,
                     gammat_over_gamman=a.gt_over_gn, polydispersity=a.polydispersity,
                     stiffness_number=a.stiffness or (1000.0 if a.dimension == 2 else 500.0))
    grains = a.grains or (1000 if a.dimension == 2 else 2000)
    name = a.name or f"{'disks' if a.dimension == 2 else 'spheres'}_mu{a.friction:g}_e{a.restitution:g}"
    out = Path(a.out).resolve()
    command = "tools/calibrate.py " + " ".join(sys.argv[1:] if argv is None else argv)
    cal = calibrate(law, out, grains, inertial, a.strain, a.seed, a.lmp, a.jobs, a.timeout)
    material = Path(a.material) if a.material else out / f"{name}.toml"
    material.parent.mkdir(parents=True, exist_ok=True)
    material.write_text(material_toml(cal, name, command))
    report(cal, out, name, command)
    print(f"calibrate: {name}: mu_s {cal.mu_s:.4f}, mu_2 {cal.mu_2:.4f}, I0 {cal.I0:.4f} (rms {cal.fit_rms:.4f}), "
          f"friction angle {cal.friction_angle:.2f} deg, phi {cal.packing:.4f}, critical {cal.critical_packing:.4f}, "
          f"E/kn {cal.youngs_over_kn:.4f}, nu {cal.poisson:.4f}; {material} ({cal.wall_s:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
