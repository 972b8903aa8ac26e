"""What the silo drivers (2D and 3D) measure alike: the discharged mass record, its steady rate
over the documented window (tools/dem_silo.py's docstring) and Nedderman's conditions."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hgtools.logs import records

TRANSIENT = 0.1              # s after the opening before the steady window starts
FIT_FMAX = 0.5               # the steady window ends when this fraction of the mass has left
RATE_BLOCKS = 10             # blocks of the window for the rate's standard error (batch means)
# the silo decks' (2D, 3D, LIGGGHTS) discharge starts at this line: a settled silo's cache key is the part before it
DISCHARGE_STAGE = "label           discharge_stage"


def walls_far(width: float, orifice: float, d: float) -> bool:
    """Nedderman's conditions for a discharge rate independent of the silo width."""
    return width > 2.5 * orifice and width > orifice + 30 * d


def steady_window(t: np.ndarray, m_out: np.ndarray, mass0: float, transient: float = TRANSIENT,
                  fmax: float = FIT_FMAX) -> tuple[np.ndarray, float]:
    """The records of the steady window (see the module docstring), as a mask over t, and its end."""
    past = np.nonzero(m_out >= fmax * mass0)[0]
    t_b = float(t[past[0]]) if len(past) else float(t[-1])
    return (t >= transient - 1e-9) & (t <= t_b + 1e-9), t_b


def fit_rate(t: np.ndarray, m_out: np.ndarray, mass0: float, transient: float = TRANSIENT,
             fmax: float = FIT_FMAX) -> dict:
    """Steady rate of the discharged mass m_out(t): the least-squares slope over the window
    (see the module docstring), the slopes of its two halves and the rms residual."""
    t = np.asarray(t, dtype=float)
    m_out = np.asarray(m_out, dtype=float)
    sel, t_b = steady_window(t, m_out, mass0, transient, fmax)
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
                fit_rel=rms / max(ms[-1] - ms[0], 1e-300), window=(float(ts[0]), float(ts[-1])),
                rate_se=rate_standard_error(ts, ms))


def rate_standard_error(t: np.ndarray, m_out: np.ndarray, blocks: int = RATE_BLOCKS) -> float:
    """The steady rate's standard error from the run's own fluctuation (batch means): the window's
    record intervals in `blocks` consecutive groups, each group's mean rate, and the standard
    deviation of those over sqrt(blocks). Grains leave an orifice in bursts, so one run's rate is
    uncertain by about 1/sqrt(grains discharged in the window); this is the figure a hybrid's rate
    error must be read against (the blocks must outlast the flow's correlation time: in the decks'
    silos the estimate is the same for blocks of 0.01 to 0.1 s)."""
    groups = np.array_split(np.arange(len(t) - 1), min(blocks, len(t) - 1))    # fit_rate: >= 6 records
    rates = np.array([(m_out[g[-1] + 1] - m_out[g[0]]) / (t[g[-1] + 1] - t[g[0]]) for g in groups])
    return float(rates.std(ddof=1) / np.sqrt(len(rates))) if len(rates) > 1 else float("nan")


def rate_ratio_se(run, reference) -> float:
    """The standard error of run.rate / reference.rate - 1 for two independent runs (each a record
    with rate and rate_se): what a rate error or a noise floor is read against."""
    return run.rate / reference.rate * float(np.hypot(run.rate_se / run.rate, reference.rate_se / reference.rate))


def recorded_time(path: Path) -> float | None:
    """The time of the last whole row a running discharge record (discharge.dat) holds, s since
    the opening; None before its first row: how far a running discharge is (the deck appends a
    row every tout, opening and closing the file, so what is there is on disk)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    for line in reversed(text[:text.rfind("\n") + 1].splitlines()):
        if line and not line.startswith("#"):
            return float(line.split()[0])
    return None


def measure(path: Path, mass0: float) -> tuple[dict, np.ndarray]:
    """The figures of a discharge record (path: discharge.dat, rows t, M_in, M_fall, M_del, N_in,
    N_fall, N_del, N_all) for a silo that held mass0: the records, the steady rate of what left
    (M_fall + M_del: in a hybrid twin part of what is inside is continuum), the fraction
    discharged and the mass balance; and the counts N_in, N_fall, N_del, N_all (columns)."""
    rec = records(path)
    t, m_in, m_fall, m_del = rec[:, 0], rec[:, 1], rec[:, 2], rec[:, 3]
    figures = dict(times=t.tolist(), m_in=m_in.tolist(), m_fall=m_fall.tolist(), m_del=m_del.tolist(),
                   end_time=float(t[-1]), discharged_fraction=float((m_fall[-1] + m_del[-1]) / mass0),
                   mass_balance=float(np.max(np.abs(m_in + m_fall + m_del - mass0)) / mass0),
                   **fit_rate(t, m_fall + m_del, mass0))
    # the grains that left, counted, over the same window: with the mass rate, the mass each grain
    # carried out (a hybrid's grains may carry more or less than their solid mass)
    sel, _ = steady_window(t, m_fall + m_del, mass0)
    figures["grain_rate"] = float(np.polyfit(t[sel], (rec[:, 5] + rec[:, 6])[sel], 1)[0])
    return figures, rec[:, 4:8].astype(int).T


@dataclass(kw_only=True)
class Discharge:
    """What a silo driver reports alike in 2D and 3D (masses per m of depth in 2D)."""
    width: float
    height: float
    orifice: float                 # D, m (3D: nominal)
    d: float
    rho: float
    grains: int                    # grains in the settled silo
    mass0: float                   # their mass, kg (2D: per m of depth)
    packing: float                 # area (2D) or volume (3D) fraction phi of the settled packing (bulk)
    fill_height: float             # max(y + r) of the settled grains, m
    rate: float                    # W, fitted steady rate, kg/s (2D: per m of depth)
    rate_first: float              # slope over the first half of the window
    rate_second: float             # slope over the second half
    fit_rms: float                 # rms residual of the line, kg (/m)
    fit_rel: float                 # fit_rms / mass discharged over the window
    window: tuple                  # (t_a, t_b), s after the opening
    beverloo: float                # Beverloo's estimate, kg/s (/m)
    discharged_fraction: float     # at the end of the run
    mass_balance: float            # max |M_in + M_fall + M_del - M0| / M0 over the records (nan: hybrid)
    lost: int                      # grains that left the box without being counted (-1: hybrid)
    settled_below: int             # grains below the closed floor (lid level) after settling (must be 0)
    settled_mass: float            # mass after settling (= mass after trimming)
    trimmed_mass: float            # mass right after trimming
    settle_time: float             # simulated time of the preparation, s
    max_overlap_initial: float     # largest overlap / d in the settled silo
    end_time: float                # simulated discharge time, s
    prep_wall_time: float          # s, preparation (this run, or the cached one's)
    wall_time: float               # s, the discharge
    prepared: bool                 # True if the settled silo was built in this run
    grain_rate: float = float("nan")    # grains leaving per s, fitted over the same window
    rate_se: float = float("nan")  # the rate's standard error from its own fluctuation (rate_standard_error)
    steps: int = 0                 # LAMMPS steps of the discharge
    loop_time: float = 0.0         # s, LAMMPS's summed loop times of those steps
    times: list = field(default_factory=list)      # records: s after the opening
    m_in: list = field(default_factory=list)       # in the silo
    m_fall: list = field(default_factory=list)     # below the floor, still falling
    m_del: list = field(default_factory=list)      # deleted
    log: str = ""

    @property
    def ratio(self) -> float:
        """Measured rate / Beverloo's."""
        return self.rate / self.beverloo

    @property
    def mass_per_grain(self) -> float:
        """Mass rate over grain rate: the mean mass a leaving grain carried, kg (2D: per m)."""
        return self.rate / self.grain_rate

    @property
    def halves_spread(self) -> float:
        """|rate_first - rate_second| / rate."""
        return abs(self.rate_first - self.rate_second) / self.rate

    @property
    def outlet(self) -> float:
        """The orifice as the grains see it (the 3D silo: the lattice hole's inscribed diameter)."""
        return self.orifice

    @property
    def walls_far(self) -> bool:
        return walls_far(self.width, self.outlet, self.d)

    def times_line(self, prep: str = "") -> str:
        return (f"  preparation{prep}: {self.settle_time:.3f} s simulated, wall {self.prep_wall_time:.1f} s"
                f"{' (this run)' if self.prepared else ' (cached)'}; discharge: {self.end_time:.3f} s "
                f"simulated, {self.steps} steps, wall {self.wall_time:.1f} s\n")

    def balance_text(self) -> str:
        return (f"  discharged {100 * self.discharged_fraction:.1f} %, mass balance {self.mass_balance:.1e}, "
                f"lost {self.lost}; ")

    def rate_line(self, unit: str) -> str:
        t_a, t_b = self.window
        return (f"  rate W = {self.rate:.4g} +- {self.rate_se:.2g} {unit} (fit {t_a:.3f}..{t_b:.3f} s, standard "
                f"error from {RATE_BLOCKS} blocks; halves {self.rate_first:.4g}, "
                f"{self.rate_second:.4g}, spread {100 * self.halves_spread:.1f} %; rms residual "
                f"{100 * self.fit_rel:.2f} % of the window's mass); {self.grain_rate:.1f} grains/s, "
                f"{self.mass_per_grain:.4g} {unit.split('/')[0]} each\n")
