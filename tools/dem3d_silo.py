#!/usr/bin/env python3
"""Discharge of a 3D flat-bottomed silo of square cross-section through a circular orifice
(docs/design.md sections 3 and 6), in three forms sharing one parameter set:

    --code lammps    input_decks/silo/dem_3d.lmp with Debian's stock LAMMPS (`lmp`)
    --code liggghts  input_decks/silo/liggghts_3d.in with LIGGGHTS 3.8 (`liggghts`)
    --code hybrid    dem_3d.lmp + input_decks/silo/hybrid_3d.lmp (fix hybrid/mpm, adaptive
                     zones) through tools/hybrid_launch.py (lmp_hybrid + mpm_solver)

The driver writes the initial data file (floor of frozen spheres with the orifice left out,
loose lattice of grains above it; see dem_3d.lmp's header for the scene), prepares the
settled silo with one code (pour, settle, trim, settle with the orifice closed; the deck
writes it as a data file) and discharges it, with the same code or another: every code can
start from the settled data file of any other (contact histories are not in data files, so
the codes start from the same state). By default the preparation is done by LAMMPS (the
reference; `--prep-code` changes it) and cached per parameter set in
$HYBRID_CACHE/dem3d_silo/ (or cache_dir); the discharge is then run by `--code`.

Discharged mass: M_out(t) = M_fall + M_del, the mass of the grains whose centre went below
the bottom of the floor layer (y = -d), still falling or deleted. The steady rate W is the
least-squares slope of M_out(t) over the window of tools/dem_silo.py's fit_rate (from
TRANSIENT = 0.1 s after the opening until FIT_FMAX of the mass has left, or the end).

3D Beverloo law (docs/design.md section 6): W = C rho_b sqrt(g) (D - k d)^(5/2) with C = 0.58,
k = 1.5, rho_b = phi rho, phi the packing fraction of the settled silo measured away from
the walls, the floor and the free surface. D is the inscribed diameter of the orifice in the
floor lattice (D_eff >= the nominal D; the hole's edge is the floor spheres' surface, and the
lattice leaves it a little wider than asked). Nedderman's conditions for a rate independent
of the walls are W > 2.5 D and W > D + 30 d; the reduced silo violates the second one, which
the summary flags: the comparison is a factor.

    tools/dem3d_silo.py --code lammps   --np 2 --out /tmp/s3_lmp
    tools/dem3d_silo.py --code liggghts --np 2 --out /tmp/s3_lig
    tools/dem3d_silo.py --code hybrid   --np 2 --out /tmp/s3_hyb --hvar houtlet=0.012
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dem3d_collapse import FLOOR_SPACING, LATTICE_JITTER, LATTICE_SPACING, PHI_EST, _num  # noqa: E402
from sphere_data import write_spheres  # noqa: E402
from dem_collapse import deck_vars, max_overlap, print_result, run_lammps  # noqa: E402
from dem_silo import FIT_FMAX, TRANSIENT, fit_rate, read_discharge, walls_far  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
DECKS = {
    "lammps": REPO / "input_decks" / "silo" / "dem_3d.lmp",
    "liggghts": REPO / "input_decks" / "silo" / "liggghts_3d.in",
    "hybrid": REPO / "input_decks" / "silo" / "dem_3d.lmp",
}
HYBRID_DECK = REPO / "input_decks" / "silo" / "hybrid_3d.lmp"
EXECUTABLES = {"lammps": "lmp", "liggghts": "liggghts"}

G = 9.81
BEVERLOO_C = 0.58            # docs/design.md section 6 (3D, circular orifice)
BEVERLOO_K = 1.5
PACKING_MARGIN = 3.0         # the packing fraction is measured this many d from walls, floor, top
DEFAULTS = dict(width=0.03, height=0.04, orifice=0.012, d=0.002, rho=2500.0, tout=0.01)


def cache_root(cache_dir: str | Path | None = None) -> Path:
    if cache_dir is not None:
        return Path(cache_dir) / "dem3d_silo"
    base = os.environ.get("HYBRID_CACHE", str(Path.home() / ".cache" / "hybrid-granular"))
    return Path(base) / "dem3d_silo"


def beverloo_3d(rho_b: float, orifice: float, d: float, c: float = BEVERLOO_C, k: float = BEVERLOO_K,
                g: float = G) -> float:
    """3D Beverloo rate W = C rho_b sqrt(g) (D - k d)^(5/2), kg/s."""
    return c * rho_b * math.sqrt(g) * max(orifice - k * d, 0.0) ** 2.5


def floor_lattice(width: float, orifice: float, d: float) -> tuple[np.ndarray, float, float]:
    """Centres (x, z) of the floor spheres, the lattice spacing and the inscribed diameter of
    the orifice. Spacing s = W / ceil(W / (FLOOR_SPACING d)) <= 1.2 d (the rows fill the width;
    a 0.9 d grain cannot pass a hole of four spheres of diameter d while s < 1.34 d); the
    spheres whose centre is within D/2 + d/2 of the axis are left out."""
    n = int(math.ceil(width / (FLOOR_SPACING * d) - 1e-9))
    s = width / n
    c = (np.arange(n) + 0.5) * s
    X, Z = np.meshgrid(c, c, indexing="ij")
    xz = np.column_stack([X.ravel(), Z.ravel()])
    dist = np.hypot(xz[:, 0] - 0.5 * width, xz[:, 1] - 0.5 * width)
    keep = dist >= 0.5 * orifice + 0.5 * d
    return xz[keep], s, float(2 * dist[keep].min() - d)


def box_bottom(height: float, d: float, tout: float) -> float:
    """Lowest y of the box: a grain deleted once its centre is below ysink = -3 d must not leave
    the box within two deletion intervals, falling from the top of the fill (as dem_2d.lmp)."""
    return -3 * d - 2 * tout * math.sqrt(2 * G * (height + d)) - 2 * d


def write_data(path: Path, width: float, height: float, orifice: float, d: float, seed: int,
               rho: float = 2500.0, tout: float = 0.01) -> dict:
    """Writes the initial data file both decks read (atom_style sphere: id type diameter
    density x y z): the floor (type 2, centres at y = -d/2) and the grains (type 1, diameters
    uniform in [0.9, 1.1] d) on a lattice of spacing LATTICE_SPACING d offset by up to
    +-LATTICE_JITTER d, from y = 0.6 d up until 1.08 * PHI_EST * W^2 H of grain volume."""
    rng = np.random.default_rng(seed)
    floor, spacing, d_eff = floor_lattice(width, orifice, d)
    s = LATTICE_SPACING * d
    margin = 0.55 * 1.1 * d + LATTICE_JITTER * d
    xs = np.arange(margin, width - margin + 1e-12, s)
    vmean = math.pi / 6 * d ** 3 * 1.01          # <D^3> for D uniform in [0.9, 1.1] d
    need = int(math.ceil(1.08 * PHI_EST * width * width * height / vmean))
    layers = int(math.ceil(need / len(xs) ** 2))
    ys = 0.6 * d + np.arange(layers) * s
    X, Y, Z = np.meshgrid(xs, ys, xs, indexing="ij")
    grains = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    grains += rng.uniform(-LATTICE_JITTER * d, LATTICE_JITTER * d, grains.shape)
    diam = rng.uniform(0.9 * d, 1.1 * d, len(grains))
    ytop = ys[-1] + 4 * d
    ybot = box_bottom(height, d, tout)
    floor_xyz = np.column_stack([floor[:, 0], np.full(len(floor), -0.5 * d), floor[:, 1]])
    write_spheres(path, "3D silo grains (tools/dem3d_silo.py)",
                  ((-d, width + d), (ybot, ytop), (-d, width + d)),
                  [("grains", 1, diam, rho, grains), ("floor", 2, d, rho, floor_xyz)], types=3)
    return dict(poured=len(grains), floor=len(floor), floor_spacing=spacing, orifice_eff=d_eff,
                ytop=ytop, ybot=ybot)


def read_data(path: Path) -> dict:
    """The Atoms section of a data file (written by this driver or by write_data of either
    code: id type diameter density x y z [ix iy iz]) as numpy columns, with radius and mass."""
    lines = Path(path).read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.split()[:1] == ["Atoms"])
    rows = []
    for ln in lines[i + 2:]:
        if not ln.strip():
            break
        rows.append([float(v) for v in ln.split()[:7]])
    a = np.array(rows)
    out = {c: a[:, k] for k, c in enumerate(("id", "type", "diameter", "density", "x", "y", "z"))}
    out["radius"] = 0.5 * out["diameter"]
    out["mass"] = out["density"] * math.pi / 6 * out["diameter"] ** 3
    return out


def packing_fraction(data: dict, width: float, d: float, margin: float = PACKING_MARGIN,
                     voxel: float | None = None) -> tuple[float, float]:
    """(volume fraction, fill height) of the settled grains (type 1): the spheres' volume in the
    box margin*d from the side walls, the floor (y = 0) and the free surface (max y + r),
    rasterised on voxels of d/10."""
    g = data["type"] == 1
    x, y, z, r = data["x"][g], data["y"][g], data["z"][g], data["radius"][g]
    top = float((y + r).max())
    lo = np.array([margin * d, margin * d, margin * d])
    hi = np.array([width - margin * d, top - margin * d, width - margin * d])
    h = voxel or d / 10
    n = np.maximum(((hi - lo) / h).astype(int), 1)
    covered = np.zeros(n, dtype=bool)
    cen = [lo[k] + (np.arange(n[k]) + 0.5) * h for k in range(3)]
    for xi, yi, zi, ri in zip(x, y, z, r):
        p = (xi, yi, zi)
        sl = []
        for k in range(3):
            a, b = np.searchsorted(cen[k], p[k] - ri), np.searchsorted(cen[k], p[k] + ri)
            if a == b:
                break
            sl.append((a, b))
        else:
            (a0, b0), (a1, b1), (a2, b2) = sl
            dx = (cen[0][a0:b0] - xi)[:, None, None]
            dy = (cen[1][a1:b1] - yi)[None, :, None]
            dz = (cen[2][a2:b2] - zi)[None, None, :]
            covered[a0:b0, a1:b1, a2:b2] |= dx * dx + dy * dy + dz * dz <= ri * ri
    return float(covered.mean()), top


@dataclass
class Silo3dResult:
    code: str
    width: float
    height: float
    orifice: float                 # nominal D, m
    orifice_eff: float             # inscribed diameter of the lattice hole, m
    d: float
    rho: float
    grains: int                    # grains in the settled silo
    mass0: float                   # their mass, kg
    floor_mass: float              # mass of the frozen floor spheres (type 2), kg
    packing: float                 # volume fraction of the settled packing (bulk)
    fill_height: float             # max(y + r) of the settled grains, m
    rate: float                    # W, fitted steady rate, kg/s
    rate_first: float
    rate_second: float
    fit_rms: float
    fit_rel: float
    window: tuple
    beverloo: float                # 3D Beverloo with D_eff, kg/s
    discharged_fraction: float
    mass_balance: float            # max |M_in + M_fall + M_del - M0| / M0 over the records (nan: hybrid)
    lost: int                      # grains that left the box uncounted (-1: hybrid)
    settled_below: int             # grains below the lid level after settling (must be 0)
    settled_mass: float
    trimmed_mass: float
    settle_time: float
    max_overlap_initial: float     # largest overlap / d in the settled silo
    end_time: float
    prep_code: str
    prep_wall_time: float
    wall_time: float               # s, the discharge
    prepared: bool
    steps: int = 0
    params: dict = field(default_factory=dict)
    times: list = field(default_factory=list)
    m_in: list = field(default_factory=list)
    m_fall: list = field(default_factory=list)
    m_del: list = field(default_factory=list)
    log: str = ""

    @property
    def ratio(self) -> float:
        return self.rate / self.beverloo

    @property
    def halves_spread(self) -> float:
        return abs(self.rate_first - self.rate_second) / self.rate

    @property
    def walls_far(self) -> bool:
        return walls_far(self.width, self.orifice_eff, self.d)

    def summary(self) -> str:
        t_a, t_b = self.window
        return (f"{self.code}: 3D silo W = {self.width:g} m, H = {self.height:g} m, D = {self.orifice:g} m "
                f"(inscribed {self.orifice_eff:.4g} m, D/d = {self.orifice_eff / self.d:.3g}), d = {self.d:g} m: "
                f"{self.grains} grains, {self.mass0:.4g} kg, packing fraction {self.packing:.4f}\n"
                f"  preparation ({self.prep_code}): {self.settle_time:.3f} s simulated, wall "
                f"{self.prep_wall_time:.1f} s{' (this run)' if self.prepared else ' (cached)'}; discharge: "
                f"{self.end_time:.3f} s simulated, {self.steps} steps, wall {self.wall_time:.1f} s\n"
                f"  rate W = {self.rate:.4g} kg/s (fit {t_a:.3f}..{t_b:.3f} s; halves {self.rate_first:.4g}, "
                f"{self.rate_second:.4g}, spread {100 * self.halves_spread:.1f} %; rms residual "
                f"{100 * self.fit_rel:.2f} % of the window's mass)\n"
                f"  3D Beverloo C = {BEVERLOO_C:g}, k = {BEVERLOO_K:g}: {self.beverloo:.4g} kg/s; "
                f"measured/Beverloo = {self.ratio:.3f}"
                f"{'' if self.walls_far else ' (silo narrower than W > D + 30 d)'}\n"
                f"  discharged {100 * self.discharged_fraction:.1f} %, mass balance {self.mass_balance:.1e}, "
                f"lost {self.lost}; {self.settled_below} grains below the lid level after settling; "
                f"max overlap/d settled {self.max_overlap_initial:.4f}")


def _failed(what: str, proc, log: Path) -> RuntimeError:
    text = log.read_text(errors="replace") if log.exists() else ""
    tail = "\n".join(text.splitlines()[-30:])
    return RuntimeError(f"failed {what} ({proc.returncode}): {' '.join(map(str, proc.args))}\n"
                        f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}\n{tail}")


def _run_deck(code: str, variables: dict, log: Path, np_: int, exe: str | None, timeout: float,
              hybrid_vars: dict | None = None):
    """One run of `code`'s deck (tools/dem_collapse.run_lammps: mpirun.sh, or hybrid_launch.py)."""
    if code == "hybrid":
        variables = dict(variables, hybrid=1, hdeck=str(HYBRID_DECK),
                         **{k: str(v) for k, v in (hybrid_vars or {}).items()})
        return run_lammps(DECKS[code], variables, log, np_, "lmp", timeout, hybrid=True)
    exe = exe or shutil.which(EXECUTABLES[code])
    if exe is None:
        raise FileNotFoundError(f"{EXECUTABLES[code]} not on PATH")
    return run_lammps(DECKS[code], variables, log, np_, exe, timeout)


SETTLED_RE = re.compile(r"^DEM3D settled: t = (\S+) s, grains (\d+), mass (\S+) kg \(after trimming (\S+)\), "
                        r"below the lid level (\d+)", re.M)


def prepare(width: float, height: float, orifice: float, d: float, seed: int, extra: dict, np_: int,
            prep_code: str = "lammps", use_cache: bool = True, cache_dir: str | Path | None = None,
            work: Path | None = None, exe: str | None = None, timeout: float = 1800) -> tuple[Path, dict, bool]:
    """The settled silo (data file) and its preparation record, from the cache or prepared
    now with `prep_code`. The orifice is part of the key (it is in the floor)."""
    tout = float(extra.get("tout", DEFAULTS["tout"]))
    rho = float(extra.get("rho", DEFAULTS["rho"]))
    hashes = "".join(hashlib.sha1(p.read_bytes()).hexdigest()[:8]
                     for p in (DECKS[prep_code], Path(__file__)))
    prep_extra = {k: v for k, v in extra.items() if k not in ("tdis", "fstop")}
    tag = json.dumps(dict(w=width, h=height, D=orifice, d=d, seed=seed, code=prep_code, np=np_, **prep_extra),
                     sort_keys=True)
    key = hashlib.sha1((tag + hashes).encode()).hexdigest()[:12]
    entry = cache_root(cache_dir) / f"w{width:g}_h{height:g}_D{orifice:g}_d{d:g}_s{seed}_{prep_code}_{key}"
    settled, info_path = entry / "settled.data", entry / "prep.json"
    if use_cache and settled.exists() and info_path.exists():
        return settled, json.loads(info_path.read_text()), False
    work = Path(work) if work else entry
    work.mkdir(parents=True, exist_ok=True)
    geo = write_data(work / "grains.data", width, height, orifice, d, seed, rho, tout)
    target = work / "settled.data"
    target.unlink(missing_ok=True)
    log = work / "log.prep.txt"
    variables = dict(data=work / "grains.data", out=work, settled=target, prep=1, discharge=0, width=width,
                     height=height, orifice=orifice, d=d, **extra)
    proc, wall = _run_deck(prep_code, variables, log, np_, exe if prep_code != "hybrid" else None, timeout)
    text = log.read_text(errors="replace") if log.exists() else ""
    m = SETTLED_RE.search(text)
    if proc.returncode != 0 or not target.exists() or not m:
        raise _failed(f"to prepare the silo with {prep_code}", proc, log)
    info = dict(settle_time=float(m.group(1)), grains=int(m.group(2)), mass=float(m.group(3)),
                trimmed_mass=float(m.group(4)), below=int(m.group(5)), wall_time=wall, code=prep_code,
                **{k: v for k, v in geo.items()})
    if use_cache:
        entry.mkdir(parents=True, exist_ok=True)
        if target != settled:
            shutil.copyfile(target, settled)
        info_path.write_text(json.dumps(info, indent=1))
        return settled, info, True
    return target, info, True


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
    out = Path(out) if out else Path.cwd() / f"dem3d_silo_{code}"
    out.mkdir(parents=True, exist_ok=True)
    for f in ("discharge.dat",):
        (out / f).unlink(missing_ok=True)
    prep_np = prep_np or np_
    settled, info, prepared = prepare(width, height, orifice, d, seed, extra, prep_np, prep_code, use_cache,
                                      cache_dir, None if use_cache else out / "prep",
                                      exe if prep_code == code else None, timeout)
    log = out / "log.txt"
    variables = dict(out=out, settled=settled, prep=0, discharge=1, width=width, height=height,
                     orifice=orifice, d=d, tdis=tdis, fstop=fstop, **extra)
    proc, wall = _run_deck(code, variables, log, np_, exe, timeout, hybrid_vars)
    text = log.read_text(errors="replace") if log.exists() else ""
    if proc.returncode != 0 or not (out / "discharge.dat").exists() or "DEM3D end:" not in text:
        raise _failed(f"in the {code} discharge", proc, log)
    mo = re.search(r"^DEM3D open: step \S+, grains (\d+), mass (\S+) kg", text, re.M)
    n0, mass0 = int(mo.group(1)), float(mo.group(2))
    rec = read_discharge(out / "discharge.dat")
    t, m_in, m_fall, m_del = rec[:, 0], rec[:, 1], rec[:, 2], rec[:, 3]
    n_in, n_fall, n_del, n_all = (rec[:, k].astype(int) for k in (4, 5, 6, 7))
    if code != "hybrid":
        balance = float(np.max(np.abs(m_in + m_fall + m_del - mass0)) / mass0)
        lost = int(max(np.max(n0 - n_all - n_del), np.max(np.abs(n_all - n_in - n_fall)),
                       round(_num(r"^DEM3D end:.* lost (\S+)", text))))
    else:  # grains become points and back: the counts do not balance (the fix's totals do)
        balance, lost = float("nan"), -1
    fit = fit_rate(t, m_fall + m_del, mass0)
    settled_state = read_data(settled)
    phi, top = packing_fraction(settled_state, width, d)
    params = {k: _num(rf"^DEM3D contact:.*\b{re.escape(k)} = (\S+)", text)
              for k in ("kn", "kt", "gamma_n", "gamma_t", "gamma_n(wall)", "gamma_t(wall)")}
    params["dt"] = _num(r"^DEM3D timestep:.*dt = (\S+) s", text)
    loops = re.findall(r"^Loop time of (\S+) on \d+ procs for (\d+) steps", text, re.M)
    rho = float(extra.get("rho", DEFAULTS["rho"]))
    return Silo3dResult(
        code=code, width=width, height=height, orifice=orifice, orifice_eff=float(info["orifice_eff"]), d=d,
        rho=rho, grains=n0, mass0=mass0, packing=phi, fill_height=top,
        floor_mass=float(settled_state["mass"][settled_state["type"] == 2].sum()),
        beverloo=beverloo_3d(phi * rho, float(info["orifice_eff"]), d),
        discharged_fraction=float((m_fall[-1] + m_del[-1]) / mass0), mass_balance=balance, lost=lost,
        settled_below=int(info["below"]), settled_mass=float(info["mass"]), trimmed_mass=float(info["trimmed_mass"]),
        settle_time=float(info["settle_time"]), max_overlap_initial=max_overlap(settled_state, d),
        end_time=float(t[-1]), prep_code=info["code"], prep_wall_time=float(info["wall_time"]), wall_time=wall,
        prepared=prepared, steps=sum(int(n) for _, n in loops), params=params, times=t.tolist(),
        m_in=m_in.tolist(), m_fall=m_fall.tolist(), m_del=m_del.tolist(),
        log="\n".join(ln for ln in text.splitlines() if ln.startswith("DEM3D ")), **fit)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--code", choices=sorted(DECKS), default="lammps", help="code of the discharge")
    p.add_argument("--prep-code", choices=("lammps", "liggghts"), default="lammps",
                   help="code that prepares the settled silo (default lammps)")
    p.add_argument("--width", type=float, default=DEFAULTS["width"], help="silo width W, m")
    p.add_argument("--height", type=float, default=DEFAULTS["height"], help="fill height H, m")
    p.add_argument("--orifice", type=float, default=DEFAULTS["orifice"], help="orifice diameter D, m")
    p.add_argument("--d", type=float, default=DEFAULTS["d"], help="mean grain diameter, m")
    p.add_argument("--tdis", type=float, default=1.0, help="discharge time after the opening, s")
    p.add_argument("--fstop", type=float, default=0.9, help="or stop once this mass fraction has left")
    p.add_argument("--np", type=int, default=1, dest="np_", help="MPI ranks")
    p.add_argument("--prep-np", type=int, default=None, help="MPI ranks of the preparation (default --np)")
    p.add_argument("--out", default=None, help="output directory")
    p.add_argument("--seed", type=int, default=2024, help="seed of the initial lattice")
    p.add_argument("--no-cache", action="store_true", help="prepare the settled silo again, in --out")
    p.add_argument("--cache-dir", default=None, help="cache directory (default $HYBRID_CACHE)")
    p.add_argument("--var", action="append", default=[], metavar="NAME=VALUE",
                   help="extra shared deck variable (mu, e, knfac, dtdiv, ketol, rho, tout)")
    p.add_argument("--hvar", action="append", default=[], metavar="NAME=VALUE",
                   help="variable of hybrid_3d.lmp (hcell, hevery, hadapt, hdepth, hband, houtlet, ...)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    a = p.parse_args(argv)
    res = run(a.code, a.width, a.height, a.orifice, a.d, a.np_, a.out, a.seed, a.prep_code, not a.no_cache,
              a.cache_dir, a.tdis, a.fstop, extra_vars=deck_vars(p, a.var),
              hybrid_vars=deck_vars(p, a.hvar, "--hvar"), prep_np=a.prep_np)
    print_result(res, a.json, ratio=res.ratio, halves_spread=res.halves_spread)
    return 0


if __name__ == "__main__":
    sys.exit(main())
