#!/usr/bin/env python3
"""Fault campaign: kills, bad input, bad files, bad numerics and a hostile peer (issue 17).

    tools/fault_campaign.py                      # everything; writes docs/results/faults.{json,md}
    tools/fault_campaign.py --quick              # a small subset (3 kills per side, a few of each kind)
    tools/fault_campaign.py --only hostile_      # cases whose name contains a string (repeatable)
    tools/fault_campaign.py --list               # the cases

Every case runs in its own directory under --work (default: a temporary one) and process group, with
an environment marker (HYBRID_FAULT_CASE) by which leftover processes are found. Outcomes:

  clear_error   non-zero exit with a message that matches what the case expects (naming the problem)
  stopped_both  (kill trials) both sides gone within 10 s, a message naming the killed process, no
                orphan, and the last restart file, its MPM state and the HDF5 output still readable
  hang          the case hit the campaign's own timeout (--timeout, default 90 s), or left a process
  crash         a signal nobody sent (segfault, abort), or no recognisable error message
  wrong_result  exit status 0 where the input should have been refused, or (kill trials) unreadable files

Writes --out/faults.json (`rows`: case, kind, outcome, seconds_to_exit, message, plus description and
the expected pattern) and --out/faults.md (a table). Uses tools/hybrid_launch.py, tools/mpirun.sh and
tools/hostile_peer.py; needs the build (tools/setup.sh) and the venv (h5py, mpi4py).
"""
from __future__ import annotations

import argparse
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from hgtools.runner import BackgroundJob

REPO = Path(__file__).resolve().parent.parent
BUILD = Path(os.environ.get("HYBRID_BUILD_DIR", REPO / "build"))
LAUNCH = REPO / "tools" / "hybrid_launch.py"
MPIRUN = REPO / "tools" / "mpirun.sh"
PEER = REPO / "tools" / "hostile_peer.py"
HANDSHAKE = REPO / "input_decks" / "hybrid" / "handshake.lmp"
MOMENTUM = REPO / "input_decks" / "hybrid" / "momentum_2d.lmp"
KINDS = ("kill", "bad_input", "file", "numerics")
OUTCOMES = ("clear_error", "stopped_both", "hang", "crash", "wrong_result")
KILL_LIMIT = 10.0        # s: both sides must be gone this soon after a kill
CRASH = re.compile(r"Segmentation fault|signal 11|signal 6\b|\(Aborted\)|core dumped|terminate called|"
                   r"Address not mapped|double free|stack smashing|Bus error|Floating point exception")


def programs() -> dict:
    path = BUILD / "lammps_fix_hybrid" / "hybrid_programs.json"
    if not path.exists():
        sys.exit(f"fault_campaign: {path} not found - build first (tools/setup.sh)")
    return json.loads(path.read_text())


def python() -> str:
    venv = os.environ.get("HYBRID_VENV")
    if venv and Path(venv, "bin", "python").exists():
        return str(Path(venv, "bin", "python"))
    return sys.executable


# ----------------------------------------------------------------------------- decks
def handshake_deck(edit: Callable[[str], str] | None = None, extra: str = "") -> str:
    text = HANDSHAKE.read_text()
    if edit is not None:
        text = edit(text)
    return text + extra


def fix_line(args: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        out = re.sub(r"^(fix\s+couple\s+all\s+hybrid/mpm)\s.*$", rf"\1 {args}", text, flags=re.M)
        assert out != text
        return out
    return edit


def sub(pattern: str, repl: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        out = re.sub(pattern, repl, text, flags=re.M)
        assert out != text, pattern
        return out
    return edit


def chain(*edits: Callable[[str], str]) -> Callable[[str], str]:
    def edit(text: str) -> str:
        for e in edits:
            text = e(text)
        return text
    return edit


FIXED_FACES = sub(r"^boundary\s+p f p", "boundary        f f p")
CORE = sub(r"^(fix\s+2d all enforce2d)", r"region core block 0.04 0.06 0.0 0.02 -0.001 0.001 units box\n\1")


# ----------------------------------------------------------------------------- cases
@dataclass
class Case:
    name: str
    kind: str
    description: str
    expect: str                          # regex the output must match for a clear error
    run: Callable[["Ctx"], list[str]] | None = None   # -> command line, run in ctx.dir
    env: dict = field(default_factory=dict)
    setup: Callable[["Ctx"], None] | None = None
    teardown: Callable[["Ctx"], None] | None = None
    trial: dict | None = None            # kill trials: {"side": "mpm"|"lammps", "np": 1|2, "seed": n}
    quick: bool = False


@dataclass
class Ctx:
    dir: Path
    programs: dict
    shared: Path                         # outputs shared between cases (a restart written once)

    def deck(self, text: str, name: str = "deck.lmp") -> Path:
        p = self.dir / name
        p.write_text(text)
        return p

    def launch(self, deck: Path, *lammps_args: str, np_: int = 1, mpm_timeout: float | None = 20) -> list[str]:
        cmd = [python(), str(LAUNCH), "-np", str(np_)]
        if mpm_timeout is not None:
            cmd += ["--mpm-timeout", str(mpm_timeout)]
        return cmd + [str(deck), "-log", "none", *lammps_args]

    def hostile(self, mode: str, *peer_args: str, mpm_timeout: float = 10) -> list[str]:
        return [str(MPIRUN), "-np", "1", python(), str(PEER), mode, *peer_args, ":", "-np", "1",
                self.programs["mpm_solver"], "--coupled", "--timeout", str(mpm_timeout)]


def deck_case(name, kind, description, expect, text_of, *lammps_args, np_=1, quick=False, setup=None):
    def run(ctx: Ctx) -> list[str]:
        text = text_of(ctx) if callable(text_of) else text_of
        return ctx.launch(ctx.deck(text), "-var", "nsteps", "100", *lammps_args, np_=np_)
    return Case(name, kind, description, expect, run, quick=quick, setup=setup)


def fix_case(name, args, expect, description=None, kind="bad_input", edit=None, quick=False):
    e = fix_line(args) if edit is None else chain(edit, fix_line(args))
    return deck_case(name, kind, description or f"fix line `{args}`", expect, handshake_deck(e), quick=quick)


LMP_ERR = r"ERROR: Illegal fix hybrid/mpm command: "
MPM_TOLD = r"[\s\S]*mpm_solver: error: the DEM host ended before connecting"


def bad_fix_cases() -> list[Case]:
    table = [
        ("fix_unknown_keyword", "cell 0.01 bogus 3", "unknown keyword 'bogus'"),
        ("fix_keyword_typo", "cell 0.01 evrey 10", "unknown keyword 'evrey'"),
        ("fix_cell_negative", "cell -0.01", r"keyword 'cell' must be > 0"),
        ("fix_cell_zero", "cell 0", r"keyword 'cell' must be > 0 \(the MPM grid cell size\), not 0"),
        ("fix_cell_not_a_number", "cell abc", r"cell"),
        ("fix_model_unknown", "cell 0.01 model granite", "keyword 'model' must be drucker_prager or mu_i"),
        ("fix_every_zero", "cell 0.01 every 0", "keyword 'every' needs a positive integer"),
        ("fix_timeout_missing_value", "cell 0.01 timeout", "keyword 'timeout' needs a value"),
        ("fix_timeout_negative", "cell 0.01 timeout -5", "timeout"),
        ("fix_idle_negative", "cell 0.01 idle -1", "idle"),
        ("fix_continuum_region_unknown", "cell 0.01 continuum nowhere", "continuum region 'nowhere' does not exist"),
        ("fix_weight_above_one", "cell 0.01 weight 1.5", "keyword 'weight'.*must be between 0 and 1"),
        ("fix_poisson_half", "cell 0.01 poisson 0.5", "poisson"),
        ("fix_friction_95", "cell 0.01 friction 95", "friction"),
        ("fix_cfl_zero", "cell 0.01 cfl 0", "cfl"),
        ("fix_pic_two", "cell 0.01 pic 2", "pic"),
        ("fix_points_per_cell_9", "cell 0.01 points_per_cell 9", "points_per_cell"),
        ("fix_container_three_values", "cell 0.01 container 0 INF", "keyword 'container' needs 4 values"),
        ("fix_material_missing", "cell 0.01 material no_such_material.toml",
         "keyword 'material': material file no_such_material.toml not found"),
        ("fix_relax_negative", "cell 0.01 relax -1", "keyword 'relax'.*must be >= 0"),
        ("fix_touch_without_adaptive", "cell 0.01 touch ylo", "keyword 'touch' needs adaptive zones"),
        ("fix_discrete_without_adaptive", "cell 0.01 discrete bed", "keyword 'discrete' needs adaptive zones"),
        ("fix_steps_per_contact_low", "cell 0.01 steps_per_contact 1.5", "steps_per_contact"),
    ]
    return [fix_case(name, args, LMP_ERR + ".*" + msg + MPM_TOLD,
                     quick=name in ("fix_keyword_typo", "fix_material_missing"))
            for name, args, msg in table]


def material_toml(ctx: Ctx) -> Path:
    p = ctx.dir / "broken_material.toml"
    p.write_text("[contact\nfriction = 0.5\n")
    return p


def lammps_cases() -> list[Case]:
    c = []
    c.append(fix_case("fix_cell_larger_than_half_box", "cell 0.08",
                      r"ERROR: Fix hybrid/mpm: the MPM process refused the connection: the grid cell size .* is more "
                      r"than half the box", quick=True))
    c.append(fix_case("fix_container_outside_box", "cell 0.01 container -1 INF INF INF",
                      r"ERROR: Fix hybrid/mpm: container x lo = -1 lies outside the box" + MPM_TOLD))
    c.append(deck_case("deck_material_file_malformed", "file", "material file with a TOML syntax error",
                       r"ERROR: .*(material|broken_material\.toml)",
                       lambda ctx: handshake_deck(fix_line(f"cell 0.01 material {material_toml(ctx)}"))))
    c.append(deck_case("deck_timestep_unstable", "bad_input", "timestep 2e-4 (1.1 steps per contact)",
                       r"ERROR: Fix hybrid/mpm: the time step .* is unstable" + MPM_TOLD,
                       handshake_deck(sub(r"^timestep\s.*$", "timestep 2.0e-4")), quick=True))
    c.append(deck_case("deck_timestep_zero", "bad_input", "timestep 0",
                       r"(ERROR: .*[Tt]ime ?step|the DEM time step must be > 0)",
                       handshake_deck(sub(r"^timestep\s.*$", "timestep 0.0"))))
    c.append(deck_case("deck_units_cgs", "bad_input", "units cgs instead of si",
                       r"(ERROR: .*units|needs units si)",
                       handshake_deck(sub(r"^units\s.*$", "units cgs"))))
    c.append(deck_case("deck_triclinic_box", "bad_input", "a triclinic box",
                       r"ERROR: Fix hybrid/mpm: the simulation box is triclinic" + MPM_TOLD,
                       handshake_deck(sub(r"^(fix\s+couple\s)", r"change_box all triclinic\n\1"))))
    c.append(deck_case("deck_gravity_changed", "bad_input", "gravity changed between runs",
                       r"ERROR: Fix hybrid/mpm: gravity changed since the coupled run started[\s\S]*"
                       r"mpm_solver: error: LAMMPS stopped the coupled run",
                       handshake_deck(extra="\nunfix grav\nfix grav all gravity 5.0 vector 0 -1 0\nrun 10\n")))
    c.append(deck_case("deck_unknown_command_mid_run", "bad_input", "an unknown LAMMPS command after a coupled run",
                       r"ERROR: Unknown command: no_such_command" + AND +
                       r"mpm_solver: error: LAMMPS stopped the coupled run",
                       handshake_deck(extra="\nno_such_command 1\n"), quick=True))
    c.append(deck_case("deck_without_fix", "bad_input", "a deck without fix hybrid/mpm",
                       r"mpm_solver: error: the DEM host ended before connecting",
                       handshake_deck(chain(sub(r"^fix\s+couple.*$", ""), sub(" f_couple", "")))))
    c.append(deck_case("deck_adaptive_cells_too_small", "bad_input",
                       "adaptive zones with cells under 2 grain diameters",
                       r"ERROR: .*(two|2) grain diameters",
                       handshake_deck(chain(FIXED_FACES, fix_line("cell 0.003 adaptive 10 every 10")))))
    c.append(deck_case("deck_output_dir_is_a_file", "file", "output directory below an existing file",
                       r"the MPM process could not set up the continuum: cannot create output directory",
                       lambda ctx: ((ctx.dir / "blocker").write_text("x"),
                                    handshake_deck(fix_line(f"cell 0.01 output {ctx.dir}/blocker/frames 1")))[1],
                       "-var", "nsteps", "20"))
    c.append(deck_case("deck_region_matches_no_cell", "numerics", "a continuum region that contains no cell centre",
                       r"ERROR: Fix hybrid/mpm: .*continuum region 'sliver'.*(no|none of the) .*cell",
                       handshake_deck(chain(FIXED_FACES, sub(
                           r"^(fix\s+2d all enforce2d)",
                           r"region sliver block 0.0501 0.0502 0.0101 0.0102 -0.001 0.001 units box\n\1"),
                           fix_line("cell 0.01 continuum sliver"))), quick=True))
    c.append(deck_case("deck_box_smaller_than_padding", "numerics",
                       "a box 1.5 cells wide, less than the grid's 3-cell padding",
                       r"ERROR: Fix hybrid/mpm: the MPM process refused the connection: the grid cell size .* is more "
                       r"than half the box along x",
                       handshake_deck(chain(sub(r"^region\s+box block 0 0.1 0 0.1",
                                                "region          box block 0 0.015 0 0.1"),
                                            sub(r"^region\s+bed block 0 0.1", "region          bed block 0 0.015")))))
    c.append(deck_case("deck_grain_leaves_grid", "numerics", "a grain shot out at 1e4 m/s",
                       r"ERROR: (Lost atoms|Fix hybrid/mpm: .*(outside|leav|off) .*grid)",
                       handshake_deck(chain(FIXED_FACES, CORE, fix_line("cell 0.01 continuum core every 1")),
                                      extra="\nset atom 1 vy 1.0e4\nrun 100\n"), quick=True))
    c.append(deck_case("deck_nan_grain_velocity", "numerics", "NaN injected into a grain's velocity between runs",
                       r"(ERROR|error): .*(NaN|non-finite|not finite)",
                       handshake_deck(chain(FIXED_FACES, CORE, fix_line("cell 0.01 continuum core every 1")),
                                      extra="\nvariable bad atom 1e308*1e308-1e308*1e308\nset atom 1 vx v_bad\n"
                                            "run 20\n"), quick=True))
    return c


# ------------------------------------------------------------------ restart / state files
def make_restart(ctx: Ctx) -> Path:
    """A coupled run that writes restart.bin and restart.bin.mpm.h5 after converting grains (once)."""
    out = ctx.shared / "restart"
    if (out / "restart.bin.mpm.h5").exists():
        return out
    out.mkdir(parents=True, exist_ok=True)
    text = handshake_deck(chain(FIXED_FACES, CORE, fix_line("cell 0.01 continuum core every 10")),
                          extra="\nwrite_restart restart.bin\n")
    (out / "deck.lmp").write_text(text)
    proc = subprocess.run(ctx.launch(out / "deck.lmp", "-var", "nsteps", "50"), cwd=out, capture_output=True,
                          text=True, timeout=120, env=job_env("setup"))
    if proc.returncode != 0 or not (out / "restart.bin.mpm.h5").exists():
        raise RuntimeError("the restart files for the file cases were not written:\n" + proc.stdout + proc.stderr)
    return out


def restart_deck(restart: Path, state: str | None, fix_args: str = "cell 0.01 continuum core every 10") -> str:
    lines = [f"read_restart {restart}", "comm_modify vel yes", "neighbor 0.0005 bin", "neigh_modify delay 0",
             "pair_style gran/hooke/history 1000.0 NULL 500.0 NULL 0.5 1", "pair_coeff * *",
             "fix grav all gravity 9.81 vector 0 -1 0", "fix integ all nve/sphere",
             "fix floor all wall/gran hooke/history 1000.0 NULL 500.0 NULL 0.5 1 yplane 0.0 NULL",
             "fix 2d all enforce2d",
             "region core block 0.04 0.06 0.0 0.02 -0.001 0.001 units box",
             f"fix couple all hybrid/mpm {fix_args}" + (f" mpm_state {state}" if state else ""),
             "run 20"]
    return "\n".join(lines) + "\n"


def file_case(name, description, expect, prepare, fix_args="cell 0.01 continuum core every 10", quick=False):
    """prepare(ctx, restart_dir) -> (restart file, state file or None) in ctx.dir."""
    def run(ctx: Ctx) -> list[str]:
        src = make_restart(ctx)
        restart, state = prepare(ctx, src)
        return ctx.launch(ctx.deck(restart_deck(restart, state, fix_args)))
    return Case(name, "file", description, expect, run, quick=quick)


def text_file(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def copy(ctx: Ctx, src: Path, name: str, keep: float | None = None) -> Path:
    data = src.read_bytes()
    if keep is not None:
        data = data[:int(len(data) * keep)]
    p = ctx.dir / name
    p.write_bytes(data)
    return p


def disk_full_run(ctx: Ctx) -> list[str]:
    """A coupled run whose frames go to a small tmpfs (root only; otherwise the case says so)."""
    small = ctx.dir / "small"
    small.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=192k", "tmpfs", str(small)], capture_output=True,
                          text=True, timeout=30)
    if proc.returncode != 0:
        raise RuntimeError(f"cannot mount a small tmpfs (needs root): {proc.stderr.strip()}")
    deck = handshake_deck(chain(FIXED_FACES, CORE,
                                fix_line(f"cell 0.01 continuum core every 10 output {small}/frames 1")))
    return ctx.launch(ctx.deck(deck), "-var", "nsteps", "5000")


def disk_full_teardown(ctx: Ctx) -> None:
    subprocess.run(["umount", "-l", str(ctx.dir / "small")], capture_output=True, timeout=30)


def file_cases() -> list[Case]:
    return [
        file_case("restart_truncated", "LAMMPS restart file cut to half its size",
                  r"ERROR.*([Rr]estart|read|file|Unexpected end)",
                  lambda ctx, s: (copy(ctx, s / "restart.bin", "restart.bin", 0.5),
                                  str(copy(ctx, s / "restart.bin.mpm.h5", "restart.bin.mpm.h5")))),
        file_case("mpm_state_truncated", "MPM state file cut to half its size",
                  r"ERROR: Fix hybrid/mpm: .*restart\.bin\.mpm\.h5",
                  lambda ctx, s: (copy(ctx, s / "restart.bin", "restart.bin"),
                                  str(copy(ctx, s / "restart.bin.mpm.h5", "restart.bin.mpm.h5", 0.5))), quick=True),
        file_case("mpm_state_missing", "mpm_state names a file that does not exist",
                  r"ERROR: Fix hybrid/mpm: .*no_such_state\.mpm\.h5",
                  lambda ctx, s: (copy(ctx, s / "restart.bin", "restart.bin"), str(ctx.dir / "no_such_state.mpm.h5"))),
        file_case("mpm_state_not_hdf5", "mpm_state names a text file",
                  r"ERROR: Fix hybrid/mpm: .*notes\.mpm\.h5",
                  lambda ctx, s: (copy(ctx, s / "restart.bin", "restart.bin"),
                                  str(text_file(ctx.dir / "notes.mpm.h5", "not HDF5\n")))),
        file_case("mpm_state_other_cell", "MPM state saved with cell 0.01, read with cell 0.0125",
                  r"ERROR: Fix hybrid/mpm: .*saved with another box, cell size or model",
                  lambda ctx, s: (copy(ctx, s / "restart.bin", "restart.bin"),
                                  str(copy(ctx, s / "restart.bin.mpm.h5", "restart.bin.mpm.h5"))),
                  fix_args="cell 0.0125 continuum core every 10"),
        file_case("restart_without_mpm_state", "restart after the conversion without mpm_state",
                  r"ERROR: Fix hybrid/mpm: the restart file was written after grains became material points",
                  lambda ctx, s: (copy(ctx, s / "restart.bin", "restart.bin"), None)),
        Case("hdf5_output_disk_full_midrun", "file",
             "HDF5 output filling a 192 KiB file system (tmpfs) in the middle of the run",
             r"(ERROR|error): .*(HDF5|points\.h5|No space left|write)", disk_full_run, teardown=disk_full_teardown,
             quick=True),
        Case("hdf5_output_disk_full", "file", "HDF5 output on a full disk (points.h5 is /dev/full)",
             r"(ERROR|error): .*(HDF5|points\.h5|No space left|write)",
             lambda ctx: (ctx.dir.joinpath("frames").mkdir(exist_ok=True),
                          ctx.dir.joinpath("frames", "points.h5").symlink_to("/dev/full"),
                          ctx.launch(ctx.deck(handshake_deck(chain(FIXED_FACES, CORE, fix_line(
                              f"cell 0.01 continuum core every 10 output {ctx.dir}/frames 1")))),
                              "-var", "nsteps", "50"))[-1], quick=True),
    ]


# ------------------------------------------------------------- programs, options, scenes
SCENE_OK = """dimension = 2
end_time = 0.001
[grid]
cell_size = 0.01
lower = [0.0, 0.0]
upper = [0.1, 0.1]
walls = "slip"
[output]
directory = "out"
interval = 0.001
[[material]]
name = "sand"
model = "drucker_prager"
density = 1500.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
friction_angle = 30.0
[[block]]
material = "sand"
shape = "box"
lower = [0.02, 0.0]
upper = [0.06, 0.04]
points_per_cell = 4
"""


def scene_case(name, description, expect, text, *args, quick=False):
    def run(ctx: Ctx) -> list[str]:
        scene = ctx.dir / "scene.toml"
        if text is not None:
            scene.write_text(text)
        return [ctx.programs["mpm_solver"], str(scene), "--quiet", *args]
    return Case(name, "bad_input", description, expect, run, quick=quick)


def program_cases() -> list[Case]:
    c = [
        scene_case("scene_missing", "mpm_solver on a scene file that does not exist",
                   r"scene.*(not exist|File does not)", None),
        scene_case("scene_toml_syntax", "scene file with a TOML syntax error", r"mpm_solver: error: .*scene\.toml",
                   "dimension = 2\n[grid\ncell_size = 0.01\n", quick=True),
        scene_case("scene_unknown_key", "scene file with a misspelt key", r"mpm_solver: error: .*cel_size",
                   SCENE_OK.replace("cell_size", "cel_size")),
        scene_case("scene_cell_negative", "scene cell_size -0.01", r"mpm_solver: error: .*cell_size",
                   SCENE_OK.replace("cell_size = 0.01", "cell_size = -0.01")),
        scene_case("scene_grid_huge", "scene with 1e12 grid nodes", r"mpm_solver: error: .*too many",
                   SCENE_OK.replace("cell_size = 0.01", "cell_size = 1e-7")),
        scene_case("scene_dimension_4", "scene dimension 4", r"mpm_solver: error: .*dimension",
                   SCENE_OK.replace("dimension = 2", "dimension = 4")),
        scene_case("scene_poisson_bad", "scene material Poisson ratio 0.7", r"mpm_solver: error: .*poisson",
                   SCENE_OK.replace("poisson_ratio = 0.3", "poisson_ratio = 0.7")),
        scene_case("scene_body_outside_grid", "scene body outside the grid", r"mpm_solver: error: .*(outside|grid)",
                   SCENE_OK.replace("upper = [0.06, 0.04]", "upper = [0.6, 0.04]")),
        scene_case("scene_end_time_nan", "scene end_time = nan", r"mpm_solver: error: .*end_time",
                   SCENE_OK.replace("end_time = 0.001", "end_time = nan")),
        scene_case("option_threads_zero", "mpm_solver --threads 0", r"threads", SCENE_OK, "--threads", "0"),
        Case("option_coupled_with_scene", "bad_input", "mpm_solver --coupled with a scene file",
             r"--coupled takes no scene file",
             lambda ctx: [ctx.programs["mpm_solver"], "--coupled", str(REPO / "input_decks" / "mpm" /
                                                                       "column_collapse_2d.toml")]),
        Case("option_timeout_negative", "bad_input", "mpm_solver --coupled --timeout -1", r"timeout",
             lambda ctx: [ctx.programs["mpm_solver"], "--coupled", "--timeout", "-1"]),
        Case("option_launch_np_zero", "bad_input", "tools/hybrid_launch.py -np 0", r"-np must be >= 1",
             lambda ctx: [python(), str(LAUNCH), "-np", "0", str(HANDSHAKE)]),
        Case("option_launch_deck_missing", "bad_input", "tools/hybrid_launch.py on a missing deck",
             r"deck .* not found", lambda ctx: [python(), str(LAUNCH), "-np", "1", str(ctx.dir / "nope.lmp")]),
        Case("peer_mpm_alone", "bad_input", "mpm_solver --coupled without LAMMPS",
             r"no DEM host process in this MPI job", lambda ctx: [ctx.programs["mpm_solver"], "--coupled"], quick=True),
        Case("peer_lammps_alone", "bad_input", "lmp_hybrid with the fix but no MPM process",
             r"ERROR: Fix hybrid/mpm: no MPM process in this MPI job",
             lambda ctx: [str(MPIRUN), "-np", "2", ctx.programs["lmp_hybrid"], "-in",
                          str(ctx.deck(handshake_deck())), "-log", "none"]),
        Case("peer_mpm_not_coupled", "bad_input", "mpm_solver without --coupled in the MPMD job",
             r"without --coupled",
             lambda ctx: [str(MPIRUN), "-np", "1", ctx.programs["lmp_hybrid"], "-in", str(ctx.deck(handshake_deck())),
                          "-log", "none", ":", "-np", "1", ctx.programs["mpm_solver"],
                          str(REPO / "input_decks" / "mpm" / "column_collapse_2d.toml")]),
        Case("peer_two_mpm_processes", "bad_input", "two mpm_solver processes in the job",
             r"runs on exactly one MPI rank",
             lambda ctx: [str(MPIRUN), "-np", "1", ctx.programs["lmp_hybrid"], "-in", str(ctx.deck(handshake_deck())),
                          "-log", "none", ":", "-np", "2", ctx.programs["mpm_solver"], "--coupled"]),
        Case("peer_release_mismatch", "bad_input", "mpm_solver of another release (HYBRID_COUPLER_FAKE_RELEASE)",
             r"ERROR: Fix hybrid/mpm: the MPM process refused the connection: version mismatch",
             lambda ctx: [str(MPIRUN), "-np", "1", ctx.programs["lmp_hybrid"], "-in", str(ctx.deck(handshake_deck())),
                          "-log", "none", ":", "-np", "1", "env", "HYBRID_COUPLER_FAKE_RELEASE=9.9.9",
                          ctx.programs["mpm_solver"], "--coupled"]),
    ]
    return c


# ------------------------------------------------------------------------ hostile peer
HOSTILE_EXPECT = {
    # handshake: the MPM process refuses, names the problem, and the peer hears it
    "hello_wrong_protocol": r"refused the handshake: version mismatch: .*protocol \d+\), mpm_solver is .*protocol",
    "hello_wrong_release": r"refused the handshake: version mismatch: fix hybrid/mpm is release 9\.9\.9",
    "hello_truncated": r"refused the handshake: version mismatch: .*a 100-byte Hello",
    "hello_empty": r"refused the handshake: version mismatch: .*a 0-byte Hello",
    "hello_oversized": r"refused the handshake: version mismatch: .*a 1049240-byte Hello",
    "hello_wrong_tag": r"mpm_solver: error: protocol error: received an unknown message \(tag 4242, 688 bytes\)",
    "hello_step_first": r"mpm_solver: error: protocol error: received StepHeader \(tag 7310, 56 bytes\) from the DEM host "
                        r"while waiting for the handshake",
    "hello_units_lj": r"refused the handshake: .*units 'lj', mpm_solver needs units si",
    "hello_dimension_4": r"refused the handshake: dimension 4 is not supported",
    "hello_cell_nan": r"refused the handshake: the grid cell size must be > 0",
    "hello_dt_negative": r"refused the handshake: the DEM time step must be > 0",
    "hello_model_unknown": r"refused the handshake: unknown constitutive model id 7",
    "hello_every_zero": r"refused the handshake: the exchange interval must be >= 1",
    "hello_box_inverted": r"refused the handshake: the box is empty or not finite along x",
    "hello_box_nan": r"refused the handshake: the box is empty or not finite along x",
    "hello_huge_grid": r"refused the handshake: the grid cell size .* gives a grid of .* nodes, which needs "
                       r"about .* GB",
    "hello_poisson_bad": r"refused the handshake: the continuum's material .*oisson",
    "hello_gravity_nan": r"refused the handshake: the gravity is not finite",
    "hello_cfl_zero": r"refused the handshake: the Courant number cfl must be in \(0, 1\]",
    "hello_container_outside": r"refused the handshake: the container along x .* leaves the box",
    "hello_points_per_axis_0": r"refused the handshake: points per cell and axis must be 1 to 4",
    "hello_silent": r"mpm_solver: error: no reply from the DEM host within 5 s while waiting for the handshake",
    "hello_die": r"exited on signal 9",
    # exchanges: the MPM process answers with an error acknowledgement naming the problem
    "header_truncated": r"answered with an error: protocol error: .*has 30 bytes, expected 56",
    "header_oversized": r"answered with an error: protocol error: .*has 120 bytes, expected 56",
    "header_time_nan": r"answered with an error: protocol error: the step header of step 30 holds a non-finite",
    "header_time_backwards": r"answered with an error: .*the DEM time went backwards",
    "header_time_jump": r"answered with an error: protocol error: the step header of step 30 is at t = 1000000",
    "header_next_time_inf": r"answered with an error: protocol error: the step header of step 30 holds a non-finite",
    "header_kind_unknown": r"answered with an error: protocol error: the step header of step 30 has an unknown kind 99",
    "records_node_off_grid": r"answered with an error: .*node 1000000000 outside the grid",
    "records_node_max": r"answered with an error: .*node 18446744073709551615 outside the grid",
    "records_nan_momentum": r"answered with an error: .*sent a non-finite \(NaN or inf\) mass or momentum for node 144",
    "records_nan_mass": r"answered with an error: .*sent a non-finite \(NaN or inf\) mass or momentum for node 144",
    "records_negative_mass": r"answered with an error: .*sent a negative mass or momentum for node 144",
    "records_inf_momentum": r"answered with an error: .*sent a non-finite \(NaN or inf\) mass or momentum for node 144",
    "records_ragged": r"answered with an error: protocol error: .*not a multiple of 40",
    "records_oversized": r"answered with an error: .*outside the grid",
    "out_of_order_records_first": r"answered with an error: protocol error: received NodeRecords "
                                  r"\(tag 7314, 120 bytes\) from the DEM host while waiting for the next message",
    "out_of_order_two_headers": r"answered with an error: protocol error: received StepHeader \(tag 7310, 56 bytes\) "
                                r"from the DEM host while "
                                r"waiting for the grain node sums",
    "unknown_tag": r"answered with an error: protocol error: received an unknown message \(tag 4242, 7 bytes\)",
    "reply_tag_from_dem": r"answered with an error: protocol error: received StepAck",
    "finish_truncated": r"answered with an error: protocol error: .*has 8 bytes, expected 16",
    "abort_note_oversized": r"answered with an error: protocol error: .*has 1000 bytes, expected 256",
    "state_save_bad_path": r"answered with an error: .*/nonexistent/dir/state\.mpm\.h5",
    "state_load_missing": r"answered with an error: .*/nonexistent/state\.mpm\.h5",
    "state_load_not_hdf5": r"answered with an error: .*README\.md",
    "rezone_zone_map_short": r"answered with an error: .*the zone map has 10 cells",
    "rezone_zone_value_bad": r"answered with an error: .*the zone map gives cell 0 the unknown zone 7",
    "rezone_volume_off_grid": r"answered with an error: .*cell 1000000000 outside the grid",
    "rezone_volume_nan": r"answered with an error: .*non-finite or negative grain volume, mass or kinetic energy for cell 40",
    "die_mid_exchange": r"exited on signal 9",
    "hang_mid_exchange": r"mpm_solver: error: no reply from the DEM host within 5 s while waiting for the grain node sums",
}
HOSTILE_QUICK = ("hello_truncated", "header_truncated", "records_node_off_grid", "records_nan_momentum",
                 "out_of_order_two_headers", "die_mid_exchange")


def hostile_cases() -> list[Case]:
    sys.path.insert(0, str(REPO / "tools"))
    import hostile_peer
    out = []
    for mode, (_, text) in hostile_peer.MODES.items():
        if mode == "valid":
            continue
        out.append(Case(f"peer_{mode}", "numerics" if "nan" in mode or "inf" in mode else "bad_input",
                        f"hostile peer: {text}", HOSTILE_EXPECT[mode],
                        (lambda m: lambda ctx: ctx.hostile(m, mpm_timeout=5 if m == "hello_silent" else 10))(mode),
                        quick=mode in HOSTILE_QUICK))
    return out


# -------------------------------------------------------------------------- kill trials
def kill_deck(ctx: Ctx) -> Path:
    text = MOMENTUM.read_text()
    text = re.sub(r"^(fix\s+couple\s.*)$", rf"\1 output {ctx.dir}/frames 20", text, flags=re.M)
    text = text.replace("run             ${nsteps}", "restart 100 restart.*.bin\nrun             ${nsteps}")
    return ctx.deck(text)


def kill_cases(trials: int, quick_trials: int) -> list[Case]:
    out = []
    for side in ("mpm", "lammps"):
        for np_ in (1, 2):
            for k in range(trials):
                out.append(Case(f"kill_{side}_np{np_}_{k}", "kill",
                                f"kill -9 {'the MPM process' if side == 'mpm' else 'a LAMMPS rank'} at a random step "
                                f"({np_} LAMMPS rank(s))",
                                r"exited on signal 9 \(Killed\)" + AND +
                                r"hybrid_launch: the coupled job failed .*, rank "
                                rf"{np_} is mpm_solver", trial=dict(side=side, np=np_, seed=1000 * np_ + k),
                                quick=k < quick_trials and np_ == 2))
    return out


# ------------------------------------------------------------------------------ running
def job_env(marker: str, extra: dict | None = None) -> dict:
    e = dict(os.environ, HYBRID_BUILD_DIR=str(BUILD), OMP_NUM_THREADS="1", HYBRID_FAULT_CASE=marker)
    if os.geteuid() == 0:
        e.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    e.update(extra or {})
    return e


def marked_pids(marker: str) -> list[int]:
    """Processes whose environment carries HYBRID_FAULT_CASE=marker (leftovers of a case)."""
    needle = f"HYBRID_FAULT_CASE={marker}".encode()
    pids = []
    for p in Path("/proc").iterdir():
        if not p.name.isdigit() or int(p.name) == os.getpid():
            continue
        try:
            if needle in (p / "environ").read_bytes().split(b"\0"):
                state = (p / "stat").read_text().rsplit(")", 1)[-1].split()[0]
                if state != "Z":
                    pids.append(int(p.name))
        except OSError:
            continue
    return pids


def program_pids(marker: str, name: str) -> list[int]:
    out = []
    for pid in marked_pids(marker):
        try:
            argv0 = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[0]
        except OSError:
            continue
        if argv0.endswith(name.encode()):
            out.append(pid)
    return out


AND = r"[\s\S]*"   # in an expected pattern: "and, anywhere in the output (either program may print first)"


def matches(expect: str, text: str) -> re.Match | None:
    """The match of the first part of `expect` if every part (split at AND) is found, else None."""
    parts = [re.search(p, text) for p in expect.split(AND)]
    return parts[0] if all(parts) else None


def best_message(text: str, expect: str) -> str:
    m = matches(expect, text)
    if m:
        # the line holding the end of the first part's match: the message naming the problem
        start = text.rfind("\n", 0, m.end() - 1) + 1
        end = text.find("\n", m.end() - 1)
        line = text[start:end if end >= 0 else None].strip()
        return line[:300]
    for pattern in (r"^.*ERROR.*$", r"^.*error:.*$", r"^hostile_peer: .*(error|refused|no answer).*$",
                    r"^.*exited on signal.*$"):
        m = re.search(pattern, text, flags=re.M)
        if m:
            return m.group(0).strip()[:300]
    return ""


def cleanup(marker: str) -> list[int]:
    left = marked_pids(marker)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return left


def tidy(message: str, ctx: Ctx) -> str:
    """The message without machine-specific parts: source locations, the work and repository paths."""
    message = re.sub(r" \(\S+\.(cpp|h):\d+\)", "", message)
    return message.replace(str(ctx.dir.parent), "<work>").replace(str(REPO), "<repo>")


def run_case(case: Case, ctx: Ctx, timeout: float) -> dict:
    row = run_case_raw(case, ctx, timeout)
    row["message"] = tidy(row["message"], ctx)
    return row


def run_case_raw(case: Case, ctx: Ctx, timeout: float) -> dict:
    marker = f"{case.name}-{uuid.uuid4().hex[:8]}"
    env = job_env(marker, case.env)
    row = dict(case=case.name, kind=case.kind, description=case.description, expect=case.expect)
    try:
        if case.trial is not None:
            return {**row, **kill_trial(case, ctx, env, marker, timeout)}
        cmd = case.run(ctx)
    except Exception as e:   # noqa: BLE001 - a broken case is reported, not fatal
        return {**row, "outcome": "crash", "seconds_to_exit": None, "message": f"campaign error: {e!r}"}
    try:
        return {**row, **run_command(case, ctx, cmd, env, marker, timeout)}
    finally:
        if case.teardown is not None:
            case.teardown(ctx)


def run_command(case: Case, ctx: Ctx, cmd: list[str], env: dict, marker: str, timeout: float) -> dict:
    (ctx.dir / "command.txt").write_text(" ".join(cmd) + "\n")
    job = BackgroundJob(cmd, ctx.dir, env)
    rc = job.wait(timeout)
    elapsed = time.monotonic() - job.t0
    if rc is None:
        job.kill()
    left = cleanup(marker)
    text = job.text
    (ctx.dir / "output.txt").write_text(text)
    message = best_message(text, case.expect)
    if rc is None:
        outcome, message = "hang", f"no exit within {timeout:g} s; last output: {message or text[-200:]}"
    elif left:
        outcome, message = "hang", f"exited {rc} but left processes {left}: {message}"
    elif rc == 0:
        outcome = "wrong_result"
    elif CRASH.search(text):
        outcome, message = "crash", CRASH.search(text).group(0) + ": " + message
    elif matches(case.expect, text):
        outcome = "clear_error"
    else:
        outcome = "crash"
        message = f"(no message matching /{case.expect}/) " + message
    return {"outcome": outcome, "seconds_to_exit": round(elapsed, 2), "exit_status": rc, "message": message}


def reads_back(ctx: Ctx, restart: Path) -> bool:
    """Whether LAMMPS (the coupled build) reads the restart file back without error."""
    check = ctx.dir / "read_back.lmp"
    check.write_text(f"read_restart {restart}\n")
    proc = subprocess.run([ctx.programs["lmp_hybrid"], "-in", str(check), "-log", "none", "-screen", "none"],
                          cwd=ctx.dir, capture_output=True, text=True, timeout=60, env=job_env("readback"))
    return proc.returncode == 0


def readable_files(ctx: Ctx) -> tuple[bool, str]:
    """The last restart file (read back by LAMMPS), its MPM state and the HDF5 output (h5py)."""
    import h5py
    notes = []
    ok = True
    restarts = sorted(ctx.dir.glob("restart.*.bin"), key=lambda p: int(p.name.split(".")[1]))
    if restarts:
        last = restarts[-1]
        if reads_back(ctx, last):
            notes.append(f"{last.name} ok")
        elif len(restarts) > 1 and reads_back(ctx, restarts[-2]):
            # LAMMPS writes a restart file in place: a kill while it writes one leaves it cut
            # short, and a run continues from the one before (which must then be whole).
            notes.append(f"{last.name} cut short by the kill; {restarts[-2].name} ok")
            restarts = restarts[:-1]
        else:
            ok = False
            notes.append(f"{last.name} unreadable")
        # The MPM process saves its state after LAMMPS has written the restart file: a kill
        # between the two leaves the newest restart without one, and the newest complete pair
        # is the previous restart (a run continues from that; mpm_state names the file).
        paired = [r for r in restarts if Path(str(r) + ".mpm.h5").exists()]
        if paired:
            state = Path(str(paired[-1]) + ".mpm.h5")
            whose = "its" if paired[-1] == restarts[-1] else f"not written; {paired[-1].name}'s"
            try:
                with h5py.File(state, "r") as f:
                    list(f.keys())
                notes.append(f"{whose} .mpm.h5 ok")
            except OSError as e:
                ok = False
                notes.append(f"{whose} .mpm.h5 unreadable ({e})")
    else:
        notes.append("no restart file yet")
    h5 = ctx.dir / "frames" / "points.h5"
    if h5.exists():
        try:
            with h5py.File(h5, "r") as f:
                frames = [k for k in f.keys()]
                n = 0
                def visit(_name, obj):
                    nonlocal n
                    if isinstance(obj, h5py.Dataset):
                        obj[()]
                        n += 1
                f.visititems(visit)
            notes.append(f"points.h5 ok ({len(frames)} groups, {n} datasets read)")
        except (OSError, KeyError, RuntimeError) as e:
            ok = False
            notes.append(f"points.h5 unreadable ({e})")
    else:
        notes.append("no points.h5 yet")
    return ok, "; ".join(notes)


def kill_trial(case: Case, ctx: Ctx, env: dict, marker: str, timeout: float) -> dict:
    t = case.trial
    rng = random.Random(t["seed"])
    job = BackgroundJob(ctx.launch(kill_deck(ctx), "-var", "nsteps", "100000000", np_=t["np"], mpm_timeout=60),
                        ctx.dir, env)
    try:
        if job.wait_for(r"mpm_solver: handshake ok", 60) is None:
            job.kill()
            return dict(outcome="crash", seconds_to_exit=None, message="the job did not start: " + job.text[-300:])
        delay = rng.uniform(0.5, 4.0)
        time.sleep(delay)
        name = "mpm_solver" if t["side"] == "mpm" else "lmp_hybrid"
        targets = program_pids(marker, name)
        if job.proc.poll() is not None or not targets:
            job.kill()
            return dict(outcome="crash", seconds_to_exit=None,
                        message=f"nothing to kill after {delay:.2f} s: " + job.text[-300:])
        victim = rng.choice(sorted(targets))
        steps = re.findall(r"^\s*(\d+)\s+\d+\s", job.text, flags=re.M)
        t_kill = time.monotonic()
        os.kill(victim, signal.SIGKILL)
        rc = job.wait(timeout)
        elapsed = time.monotonic() - t_kill
        if rc is None:
            job.kill()
        time.sleep(0.3)
        left = cleanup(marker)
    finally:
        (ctx.dir / "output.txt").write_text(job.text)
    text = job.text
    where = f"killed {t['side']} pid {victim} after {delay:.2f} s (last thermo step {steps[-1] if steps else '?'})"
    files_ok, files = readable_files(ctx)
    m = matches(case.expect, text)
    message = f"{best_message(text, case.expect)}; {where}; files: {files}"
    if rc is None:
        outcome = "hang"
    elif left:
        outcome, message = "hang", f"orphans {left}; " + message
    elif elapsed > KILL_LIMIT or rc == 0 or not m:
        outcome = "crash" if not m else "hang"
    elif not files_ok:
        outcome = "wrong_result"
    else:
        outcome = "stopped_both"
    return dict(outcome=outcome, seconds_to_exit=round(elapsed, 2), exit_status=rc, message=message)


# ------------------------------------------------------------------------------ report
def all_cases(trials: int, quick_trials: int) -> list[Case]:
    return kill_cases(trials, quick_trials) + bad_fix_cases() + lammps_cases() + file_cases() + program_cases() + \
        hostile_cases()


def write_report(rows: list[dict], out: Path, command: str) -> None:
    out.mkdir(parents=True, exist_ok=True)
    counts: dict = {}
    for r in rows:
        counts.setdefault(r["kind"], {}).setdefault(r["outcome"], 0)
        counts[r["kind"]][r["outcome"]] += 1
    kills = [r["seconds_to_exit"] for r in rows if r["kind"] == "kill" and r["seconds_to_exit"] is not None]
    summary = dict(cases=len(rows), bad_inputs=sum(1 for r in rows if r["kind"] != "kill"), counts=counts,
                   kill_seconds_max=max(kills) if kills else None,
                   kill_seconds_mean=round(sum(kills) / len(kills), 2) if kills else None,
                   hangs=sum(1 for r in rows if r["outcome"] == "hang"),
                   crashes=sum(1 for r in rows if r["outcome"] == "crash"),
                   wrong_results=sum(1 for r in rows if r["outcome"] == "wrong_result"))
    (out / "faults.json").write_text(json.dumps(dict(command=command, summary=summary, rows=rows), indent=1) + "\n")
    lines = ["# Fault campaign", "", f"Written by `{command}` (tools/fault_campaign.py; docs/fix_hybrid_mpm.md, "
             "\"Failures\"). Each row is one case: a process killed with `kill -9` at a random step, or one bad input "
             "(deck, fix line, scene file, option, time step, peer, file) or a hostile stand-in for LAMMPS "
             "(tools/hostile_peer.py, mpi4py) speaking the wire protocol wrongly.", "",
             f"{summary['cases']} cases, {summary['bad_inputs']} distinct bad inputs; "
             f"hangs {summary['hangs']}, crashes {summary['crashes']}, wrong results {summary['wrong_results']}. "
             + (f"Kills: both sides gone after {summary['kill_seconds_mean']} s on average, "
                f"{summary['kill_seconds_max']} s at most." if kills else ""), "",
             "| kind | " + " | ".join(OUTCOMES) + " |", "| --- |" + " --- |" * len(OUTCOMES)]
    for kind in KINDS:
        if kind in counts:
            lines.append(f"| {kind} | " + " | ".join(str(counts[kind].get(o, 0)) for o in OUTCOMES) + " |")
    lines += ["", "| case | kind | what | outcome | s to exit | message |", "| --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        msg = r["message"].replace("|", "\\|").replace("\n", " ")
        what = r["description"].replace("|", "\\|")
        lines.append(f"| `{r['case']}` | {r['kind']} | {what} | {r['outcome']} | {r['seconds_to_exit']} | {msg} |")
    (out / "faults.md").write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Run the fault campaign and write docs/results/faults.{json,md}.")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "results", help="where faults.json/.md go")
    ap.add_argument("--work", type=Path, default=None, help="keep each case's directory here (default: temporary)")
    ap.add_argument("--quick", action="store_true", help="a small subset (the cases marked quick)")
    ap.add_argument("--only", action="append", default=[], help="only cases whose name contains this (repeatable)")
    ap.add_argument("--kind", action="append", choices=KINDS, default=[], help="only cases of this kind")
    ap.add_argument("--trials", type=int, default=10, help="kill trials per side and rank count (default 10)")
    ap.add_argument("--timeout", type=float, default=90.0, help="s before a case counts as a hang (default 90)")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--no-write", action="store_true", help="print the rows, do not write the report")
    args = ap.parse_args(argv)

    cases = all_cases(args.trials, 3)
    if args.quick:
        cases = [c for c in cases if c.quick]
    if args.only:
        cases = [c for c in cases if any(s in c.name for s in args.only)]
    if args.kind:
        cases = [c for c in cases if c.kind in args.kind]
    if args.list:
        for c in cases:
            print(f"{c.name:40s} {c.kind:10s} {c.description}")
        return 0
    progs = programs()
    work = args.work or Path(tempfile.mkdtemp(prefix="fault_campaign_"))
    work.mkdir(parents=True, exist_ok=True)
    shared = work / "_shared"
    shared.mkdir(exist_ok=True)
    rows = []
    for i, case in enumerate(cases, 1):
        d = work / case.name
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        row = run_case(case, Ctx(d, progs, shared), args.timeout)
        rows.append(row)
        print(f"[{i}/{len(cases)}] {case.name}: {row['outcome']} in {row['seconds_to_exit']} s - "
              f"{row['message'][:160]}",
              flush=True)
    given = list(argv if argv is not None else sys.argv[1:])
    for opt in ("--work", "--out"):   # where things went, not what ran
        while opt in given:
            k = given.index(opt)
            del given[k:k + 2]
    command = " ".join(["tools/fault_campaign.py", *given])
    if args.no_write:
        print(json.dumps(rows, indent=1))
    else:
        write_report(rows, args.out, command.strip())
        print(f"wrote {args.out / 'faults.json'} and {args.out / 'faults.md'}")
    if args.work is None:
        shutil.rmtree(work, ignore_errors=True)
    bad = [r for r in rows if r["outcome"] in ("hang", "crash", "wrong_result")]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
