#!/usr/bin/env python3
"""Pure-DEM reference of the discharge of a planar (2D) flat-bottomed silo (docs/design.md
sections 3 and 6).

Runs input_decks/silo/dem_2d.lmp with Debian's stock LAMMPS (`lmp`): a silo of width W
filled to height H with disks of mean diameter d, settled with the orifice closed, then
the central orifice of width D opens. Reads the discharged mass against time
(<out>/discharge.dat), fits the steady discharge rate and compares it with the 2D Beverloo
law.

The settled silo (pouring + settling + trimming) is cached per parameter set in
$HYBRID_CACHE/dem_silo/ (default ~/.cache/hybrid-granular/dem_silo/, or cache_dir), so
repeated runs only redo the discharge. The preparation and the discharge are two LAMMPS
runs (the deck can also do both in one), so that their wall times are measured apart.

Discharged mass (documented choice). M_out(t) = M0 - M_in(t): the mass of the grains whose
centre has gone below the floor plane y = 0, whether still falling or already deleted by
the deck.

Steady window (documented choice). The rate W is the slope of a least-squares line through
M_out(t) from t_a = TRANSIENT after the opening (the flow is established within a few
sqrt(D/g), ~0.05 s; 0.1 s leaves a margin) to t_b = the first record at which FIT_FMAX =
50 % of the initial mass has left, or the end of the run. Past about half the mass the
free surface reaches the region over the orifice and the rate starts to fall. Steadiness
is judged on the same window: the slopes of its two halves, and the rms residual of the
line relative to the mass discharged over the window.

2D Beverloo law. For a slot of width D in a planar silo the mass rate per unit depth is
    W = C rho_b sqrt(g) (D - k d)^(3/2),     rho_b = phi rho,
the 2D form of docs/design.md section 6's law (which is the 3D one, exponent 5/2). phi is the
area fraction of the settled packing, measured here away from the walls, the floor and the
free surface. We take k = 1.5 (docs/design.md) and C = pi/4 ~ 0.785. That C is the free-fall
arch estimate with the self-similar outlet profiles of Janda, Zuriguel and Maza (PRL 108,
248001, 2012) for 2D silos: vertical velocity sqrt(g D) sqrt(1 - (2x/D)^2) across the
orifice, with the outlet packing close to the bulk one, integrates to (pi/4) rho_b sqrt(g)
D^(3/2). It is an approximation (we could not check the paper's fitted constants from the
reference corpus; the outlet is looser than the bulk, which lowers C, and 2D experiments
and simulations in the literature give C of order 0.6-1), so the comparison is a factor,
not a percentage. The silo is wide enough for the walls not to matter when W > 2.5 D and
W > D + 30 d (Nedderman's conditions, quoted by Mankoc et al., Granular Matter 9, 407,
2007); the reduced test size violates the second one and is flagged in the summary.

    tools/dem_silo.py --width 0.1 --height 0.15 --orifice 0.02 --d 0.002 --np 2 --out /tmp/silo
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DECK = REPO / "input_decks" / "silo" / "dem_2d.lmp"
HYBRID_DECK = REPO / "input_decks" / "silo" / "hybrid_2d.lmp"
sys.path.insert(0, str(Path(__file__).resolve().parent))
from dem_collapse import (add_run_arguments, deck_vars, max_overlap, print_result, read_dump,  # noqa: E402
                          run_lammps)

G = 9.81
BEVERLOO_C2D = math.pi / 4   # free-fall arch with Janda et al. 2012's outlet profiles (see above)
BEVERLOO_K = 1.5             # docs/design.md section 6
TRANSIENT = 0.1              # s after the opening before the steady window starts
FIT_FMAX = 0.5               # the steady window ends when this fraction of the mass has left
PACKING_MARGIN = 3.0         # the packing fraction is measured this many d from walls, floor, top


def cache_root(cache_dir: str | Path | None = None) -> Path:
    if cache_dir is not None:
        return Path(cache_dir) / "dem_silo"
    base = os.environ.get("HYBRID_CACHE", str(Path.home() / ".cache" / "hybrid-granular"))
    return Path(base) / "dem_silo"


def beverloo_2d(rho_b: float, orifice: float, d: float, c: float = BEVERLOO_C2D,
                k: float = BEVERLOO_K, g: float = G) -> float:
    """2D Beverloo rate W = C rho_b sqrt(g) (D - k d)^(3/2), kg/s per m of depth."""
    return c * rho_b * math.sqrt(g) * max(orifice - k * d, 0.0) ** 1.5


def walls_far(width: float, orifice: float, d: float) -> bool:
    """Nedderman's conditions for a discharge rate independent of the silo width."""
    return width > 2.5 * orifice and width > orifice + 30 * d


@dataclass
class SiloResult:
    width: float
    height: float
    orifice: float
    d: float
    rho: float
    grains: int                    # grains in the settled silo
    mass0: float                   # their mass, kg per m of depth
    packing: float                 # area fraction phi of the settled packing (bulk)
    fill_height: float             # max(y + r) of the settled grains, m
    rate: float                    # W, fitted steady rate, kg/s per m of depth
    rate_first: float              # slope over the first half of the window
    rate_second: float             # slope over the second half
    fit_rms: float                 # rms residual of the line, kg/m
    fit_rel: float                 # fit_rms / mass discharged over the window
    window: tuple                  # (t_a, t_b), s after the opening
    beverloo: float                # 2D Beverloo estimate, kg/s per m
    discharged_fraction: float     # at the end of the run
    mass_balance: float            # max |M_in + M_fall + M_del - M0| / M0 over the records
    lost: int                      # grains that left the box without being counted
    below_at_open: int             # grains below the floor when the orifice opened (must be 0)
    settled_below: int             # grains below the closed floor after settling (must be 0)
    settled_mass: float            # mass after settling (= mass after trimming), kg/m
    trimmed_mass: float            # mass right after trimming, kg/m
    settle_time: float             # simulated time of the preparation, s
    max_overlap_initial: float     # largest overlap / d in the settled silo
    end_time: float                # simulated discharge time, s
    prep_wall_time: float          # s, preparation (this run, or the cached one's)
    wall_time: float               # s, the discharge
    prepared: bool                 # True if the settled silo was built in this run
    steps: int = 0                 # LAMMPS steps of the discharge
    loop_time: float = 0.0         # s, LAMMPS's summed loop times of those steps
    times: list = field(default_factory=list)      # records: s after the opening
    m_in: list = field(default_factory=list)       # kg/m in the silo
    m_fall: list = field(default_factory=list)     # kg/m below the floor, still falling
    m_del: list = field(default_factory=list)      # kg/m deleted
    log: str = ""

    @property
    def ratio(self) -> float:
        """Measured rate / Beverloo's."""
        return self.rate / self.beverloo

    @property
    def halves_spread(self) -> float:
        """|rate_first - rate_second| / rate."""
        return abs(self.rate_first - self.rate_second) / self.rate

    @property
    def walls_far(self) -> bool:
        return walls_far(self.width, self.orifice, self.d)

    def summary(self) -> str:
        t_a, t_b = self.window
        return (f"DEM silo W = {self.width:g} m, H = {self.height:g} m, D = {self.orifice:g} m "
                f"(D/d = {self.orifice / self.d:.3g}), d = {self.d:g} m: {self.grains} grains, "
                f"{self.mass0:.4g} kg/m, packing fraction {self.packing:.4f}\n"
                f"  preparation: {self.settle_time:.3f} s simulated, wall {self.prep_wall_time:.1f} s"
                f"{' (this run)' if self.prepared else ' (cached)'}; discharge: {self.end_time:.3f} s "
                f"simulated, {self.steps} steps, wall {self.wall_time:.1f} s\n"
                f"  rate W = {self.rate:.4g} kg/s/m (fit {t_a:.3f}..{t_b:.3f} s; halves {self.rate_first:.4g}, "
                f"{self.rate_second:.4g}, spread {100 * self.halves_spread:.1f} %; rms residual "
                f"{100 * self.fit_rel:.2f} % of the window's mass)\n"
                f"  2D Beverloo C = {BEVERLOO_C2D:.3f}, k = {BEVERLOO_K:g}: {self.beverloo:.4g} kg/s/m; "
                f"measured/Beverloo = {self.ratio:.3f}"
                f"{'' if self.walls_far else ' (silo narrower than W > D + 30 d: walls may raise the rate)'}\n"
                f"  discharged {100 * self.discharged_fraction:.1f} %, mass balance {self.mass_balance:.1e}, "
                f"lost {self.lost}; closed orifice: {self.settled_below} grains below the floor after settling, "
                f"{self.below_at_open} at the opening; max overlap/d settled {self.max_overlap_initial:.4f}")


def packing_fraction(dump: dict, width: float, d: float, margin: float = PACKING_MARGIN,
                     pixel: float | None = None) -> tuple[float, float]:
    """(area fraction, fill height) of the settled grains: the disks' area in the window
    margin*d from the side walls, the floor and the free surface (max y + r), rasterised on
    pixels of d/20."""
    x, y, r = dump["x"], dump["y"], dump["radius"]
    top = float((y + r).max())
    x0, x1, y0, y1 = margin * d, width - margin * d, margin * d, top - margin * d
    h = pixel or d / 20
    nx, ny = int((x1 - x0) / h), int((y1 - y0) / h)
    covered = np.zeros((ny, nx), dtype=bool)
    xc = x0 + (np.arange(nx) + 0.5) * h
    yc = y0 + (np.arange(ny) + 0.5) * h
    for xi, yi, ri in zip(x, y, r):
        if xi + ri < x0 or xi - ri > x1 or yi + ri < y0 or yi - ri > y1:
            continue
        i0, i1 = np.searchsorted(yc, yi - ri), np.searchsorted(yc, yi + ri)
        j0, j1 = np.searchsorted(xc, xi - ri), np.searchsorted(xc, xi + ri)
        if i0 == i1 or j0 == j1:
            continue
        inside = (xc[None, j0:j1] - xi) ** 2 + (yc[i0:i1, None] - yi) ** 2 <= ri * ri
        covered[i0:i1, j0:j1] |= inside
    return float(covered.mean()), top


def fit_rate(t: np.ndarray, m_out: np.ndarray, mass0: float, transient: float = TRANSIENT,
             fmax: float = FIT_FMAX) -> dict:
    """Steady rate of the discharged mass m_out(t): the least-squares slope over the window
    (see the module docstring), the slopes of its two halves and the rms residual."""
    t = np.asarray(t, dtype=float)
    m_out = np.asarray(m_out, dtype=float)
    past = np.nonzero(m_out >= fmax * mass0)[0]
    t_b = float(t[past[0]]) if len(past) else float(t[-1])
    sel = (t >= transient - 1e-9) & (t <= t_b + 1e-9)
    if sel.sum() < 6:
        raise RuntimeError(f"steady window {transient:.3f}..{t_b:.3f} s holds only {int(sel.sum())} "
                           f"records: the discharge is too short (or clogged)")
    ts, ms = t[sel], m_out[sel]
    slope, icpt = np.polyfit(ts, ms, 1)
    rms = float(np.sqrt(np.mean((ms - (slope * ts + icpt)) ** 2)))
    half = len(ts) // 2
    first = np.polyfit(ts[:half + 1], ms[:half + 1], 1)[0]
    second = np.polyfit(ts[half:], ms[half:], 1)[0]
    return dict(rate=float(slope), rate_first=float(first), rate_second=float(second), fit_rms=rms,
                fit_rel=rms / max(ms[-1] - ms[0], 1e-300), window=(float(ts[0]), float(ts[-1])))


def read_discharge(path: Path) -> np.ndarray:
    """discharge.dat as an array of rows t, M_in, M_fall, M_del, N_in, N_fall, N_del, N_all."""
    return np.loadtxt(path, comments="#", ndmin=2)


def settled_path(width: float, height: float, d: float, seed: int, extra: dict,
                 cache_dir: str | Path | None = None) -> Path:
    """Cache entry of the settled silo. The orifice, tdis, fstop and tout are not part of
    the key: the preparation does not depend on them (the orifice is closed)."""
    deck_hash = hashlib.sha1(DECK.read_bytes()).hexdigest()[:10]
    prep_extra = {k: v for k, v in extra.items() if k not in ("orifice", "tdis", "fstop", "tout")}
    tag = json.dumps(dict(w=width, h=height, d=d, seed=seed, **prep_extra), sort_keys=True)
    key = hashlib.sha1(tag.encode()).hexdigest()[:10]
    return (cache_root(cache_dir) / f"w{width:g}_h{height:g}_d{d:g}_s{seed}_{key}_{deck_hash}"
            / "settled.restart")


def _lammps(variables: dict, log: Path, np_: int, lmp: str,
            timeout: float, hybrid: bool = False) -> tuple[subprocess.CompletedProcess, float]:
    return run_lammps(DECK, variables, log, np_, lmp, timeout, hybrid)


def _failed(what: str, proc: subprocess.CompletedProcess, log: Path) -> RuntimeError:
    text = log.read_text() if log.exists() else ""
    tail = "\n".join(text.splitlines()[-30:])
    return RuntimeError(f"LAMMPS failed {what} ({proc.returncode}): {' '.join(map(str, proc.args))}\n"
                        f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}\n{tail}")


SETTLED_RE = re.compile(r"^DEM silo settled: t = (\S+) s, grains (\d+), mass (\S+) kg/m \(after trimming (\S+)\), "
                        r"below the floor (\d+)", re.M)


def run_dem_silo(width: float = 0.1, height: float = 0.15, orifice: float = 0.02, d: float = 0.002,
                 np_: int = 1, out: str | Path | None = None, seed: int = 12345, use_cache: bool = True,
                 cache_dir: str | Path | None = None, tdis: float = 1.0, fstop: float = 0.9,
                 lmp: str = "lmp", timeout: float = 3600, extra_vars: dict | None = None,
                 hybrid_vars: dict | None = None) -> SiloResult:
    """Runs the DEM silo discharge (preparing the settled silo unless cached) and returns
    the measured result. extra_vars: further deck variables (rho, e, mu, knfac, dtdiv, ...).
    hybrid_vars: run the discharge coupled instead (lmp_hybrid + mpm_solver, the deck's hybrid
    twin with input_decks/silo/hybrid_2d.lmp: adaptive zones) with these extra variables
    (hcell, hevery, hadapt, hdepth, hband, hyoungs, hphi); the settled silo is the DEM one."""
    extra = {k: str(v) for k, v in (extra_vars or {}).items()}
    out = Path(out) if out else Path.cwd() / f"dem_silo_w{width:g}_D{orifice:g}"
    out.mkdir(parents=True, exist_ok=True)
    settled = settled_path(width, height, d, seed, extra, cache_dir)
    info_path = settled.with_name("prep.json")
    prep = not (use_cache and settled.exists() and info_path.exists())
    common = dict(width=width, height=height, orifice=orifice, d=d, seed=seed, out=str(out), **extra)
    if prep:
        # the settled silo first (orifice closed), then the discharge from it
        target = out / "settled.restart"
        log = out / "log.prep.lammps"
        proc, prep_wall = _lammps(dict(common, settled=str(target), prep=1, discharge=0), log, np_, lmp,
                                  timeout)
        text = log.read_text() if log.exists() else ""
        m = SETTLED_RE.search(text)
        if proc.returncode != 0 or not target.exists() or not m:
            raise _failed("to prepare the silo", proc, log)
        info = dict(settle_time=float(m.group(1)), grains=int(m.group(2)), mass=float(m.group(3)),
                    trimmed_mass=float(m.group(4)), below=int(m.group(5)), wall_time=prep_wall)
        if use_cache:
            settled.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(target, settled)
            info_path.write_text(json.dumps(info, indent=1))
    else:
        target = settled
        info = json.loads(info_path.read_text())
    log = out / "log.lammps"
    variables = dict(common, settled=str(target), prep=0, tdis=tdis, fstop=fstop)
    if hybrid_vars is not None:
        variables.update(hybrid=1, hdeck=str(HYBRID_DECK), **{k: str(v) for k, v in hybrid_vars.items()})
    proc, wall = _lammps(variables, log, np_, lmp, timeout, hybrid=hybrid_vars is not None)
    text = log.read_text() if log.exists() else ""
    if proc.returncode != 0 or not (out / "discharge.dat").exists() or "DEM silo end:" not in text:
        raise _failed("in the discharge", proc, log)
    rho = float(extra.get("rho", 2500))
    mo = re.search(r"^DEM silo open: .*, grains (\d+), mass (\S+) kg/m, in the silo (\d+), "
                   r"below the floor (\d+)", text, re.M)
    if not mo:
        raise RuntimeError(f"no 'DEM silo open' line in {log}")
    ml = re.search(r"^DEM silo end: .* lost (\S+)", text, re.M)
    n0, mass0, below_open = int(mo.group(1)), float(mo.group(2)), int(mo.group(4))
    rec = read_discharge(out / "discharge.dat")
    t, m_in, m_fall, m_del = rec[:, 0], rec[:, 1], rec[:, 2], rec[:, 3]
    n_in, n_fall, n_del, n_all = (rec[:, k].astype(int) for k in (4, 5, 6, 7))
    if hybrid_vars is None:
        balance = float(np.max(np.abs(m_in + m_fall + m_del - mass0)) / mass0)
        lost = int(max(np.max(n0 - n_all - n_del), np.max(n0 - n_in - n_fall - n_del), round(float(ml.group(1)))))
    else:  # grains become points and back: the counts do not balance (the fix's totals do)
        balance, lost = float("nan"), -1
    # what left through the orifice: in the hybrid twin part of what is inside is continuum
    fit = fit_rate(t, m_fall + m_del, mass0)
    initial = read_dump(out / "initial.dump")
    phi, top = packing_fraction(initial, width, d)
    loops = re.findall(r"^Loop time of (\S+) on \d+ procs for (\d+) steps", text, re.M)
    return SiloResult(
        width=width, height=height, orifice=orifice, d=d, rho=rho, grains=n0, mass0=mass0, packing=phi,
        fill_height=top, beverloo=beverloo_2d(phi * rho, orifice, d),
        discharged_fraction=float((m_fall[-1] + m_del[-1]) / mass0), mass_balance=balance, lost=lost,
        below_at_open=below_open, settled_below=int(info["below"]), settled_mass=float(info["mass"]),
        trimmed_mass=float(info["trimmed_mass"]), settle_time=float(info["settle_time"]),
        max_overlap_initial=max_overlap(initial, d), end_time=float(t[-1]),
        prep_wall_time=float(info["wall_time"]), wall_time=wall, prepared=prep,
        steps=sum(int(n) for _, n in loops), loop_time=sum(float(s) for s, _ in loops),
        times=t.tolist(), m_in=m_in.tolist(), m_fall=m_fall.tolist(), m_del=m_del.tolist(),
        log="\n".join(ln for ln in text.splitlines() if ln.startswith("DEM ")), **fit)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--width", type=float, default=0.1, help="silo width W, m")
    p.add_argument("--height", type=float, default=0.15, help="fill height H, m")
    p.add_argument("--orifice", type=float, default=0.02, help="orifice width D, m")
    p.add_argument("--d", type=float, default=0.002, help="mean grain diameter, m")
    p.add_argument("--tdis", type=float, default=1.0, help="discharge time after the opening, s")
    p.add_argument("--fstop", type=float, default=0.9, help="or stop once this mass fraction has left")
    add_run_arguments(p, "silo")
    p.add_argument("--cache-dir", default=None, help="cache directory (default $HYBRID_CACHE)")
    p.add_argument("--var", action="append", default=[], metavar="NAME=VALUE",
                   help="extra deck variable (mu, e, knfac, dtdiv, ketol, rho, tout, ...)")
    p.add_argument("--hybrid", action="store_true",
                   help="run the discharge coupled (adaptive zones, input_decks/silo/hybrid_2d.lmp)")
    p.add_argument("--hvar", action="append", default=[], metavar="NAME=VALUE",
                   help="variable of the hybrid twin (hcell, hevery, hadapt, hdepth, hband, hyoungs, hphi)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    a = p.parse_args(argv)
    extra = deck_vars(p, a.var)
    hybrid = deck_vars(p, a.hvar, "--hvar") if a.hybrid or a.hvar else None
    res = run_dem_silo(a.width, a.height, a.orifice, a.d, a.np_, a.out, a.seed, not a.no_cache,
                       a.cache_dir, a.tdis, a.fstop, extra_vars=extra, hybrid_vars=hybrid)
    print_result(res, a.json, ratio=res.ratio, halves_spread=res.halves_spread)
    return 0


if __name__ == "__main__":
    sys.exit(main())
