"""What the silo drivers (2D and 3D) measure alike: the discharged mass record, its steady rate
over the documented window (tools/dem_silo.py's docstring) and Nedderman's conditions."""
from __future__ import annotations

from pathlib import Path

import numpy as np

TRANSIENT = 0.1              # s after the opening before the steady window starts
FIT_FMAX = 0.5               # the steady window ends when this fraction of the mass has left


def walls_far(width: float, orifice: float, d: float) -> bool:
    """Nedderman's conditions for a discharge rate independent of the silo width."""
    return width > 2.5 * orifice and width > orifice + 30 * d


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
