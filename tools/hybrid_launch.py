#!/usr/bin/env python3
"""Run a coupled LAMMPS (or LIGGGHTS) + MPM job (one MPMD mpirun).

    tools/hybrid_launch.py -np 2 deck.lmp [LAMMPS args...]
        -> tools/mpirun.sh -np 2 build/lammps_fix_hybrid/lmp_hybrid -in deck.lmp [LAMMPS args...]
                         : -np 1 build/mpm_solver/mpm_solver --coupled

    tools/hybrid_launch.py -np 2 --plugin deck.lmp
        -> the PLUGIN-enabled LAMMPS that tools/setup.sh builds, started as
           lmp_plugin -m 0 -in <wrapper>, where the wrapper deck is
               plugin load build/lammps_fix_hybrid/hybridmpmplugin.so
               include <deck>
           (-m is -mpicolor: it must come first; mpm_solver uses colour 1. This LAMMPS
           version accepts only the short form: its argument loop rejects "-mpicolor".)

    tools/hybrid_launch.py --host liggghts -np 2 deck.liggghts
        -> tools/mpirun.sh -np 2 build/lammps_fix_hybrid/liggghts_hybrid -in deck.liggghts
                         : -np 1 build/mpm_solver/mpm_solver --coupled
           (LIGGGHTS 3.8 as the DEM host: 3D decks, fixed continuum regions; see
           docs/fix_hybrid_mpm.md, "LIGGGHTS host")

Arguments after the deck go to LAMMPS (LIGGGHTS) unchanged (e.g. -var nsteps 1000 -log run.log).
tools/mpirun.sh handles running as root and adds --oversubscribe when the ranks exceed the
cores. The exit status is mpirun's; when it is not 0 a last line says which MPI rank is which
program, since Open MPI names failing processes by rank only.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def load_programs(build: Path) -> dict:
    """Paths written by lammps_fix_hybrid/CMakeLists.txt at configure time."""
    path = build / "lammps_fix_hybrid" / "hybrid_programs.json"
    if not path.exists():
        sys.exit(f"hybrid_launch: {path} not found - build first (tools/setup.sh)")
    return json.loads(path.read_text())


def compose(args: argparse.Namespace, programs: dict, wrapper_dir: Path | None) -> list[str]:
    """The full command line (mpirun.sh ... : ...)."""
    deck = Path(args.deck)
    if not deck.is_file():
        sys.exit(f"hybrid_launch: deck {deck} not found")
    mpm = programs["mpm_solver"]
    if args.host == "liggghts":
        if args.plugin:
            sys.exit("hybrid_launch: --plugin is for LAMMPS only (LIGGGHTS has no plugin loader)")
        if not programs.get("liggghts_hybrid"):
            sys.exit("hybrid_launch: liggghts_hybrid is not built: the LIGGGHTS headers were not found at "
                     "configure time (Debian package libliggghts-dev; tools/setup.sh installs it)")
    host = programs["liggghts_hybrid"] if args.host == "liggghts" else programs["lmp_hybrid"]
    for exe in [mpm] + ([] if args.plugin else [host]):
        if not Path(exe).exists():
            sys.exit(f"hybrid_launch: {exe} is not built - run tools/setup.sh")
    if args.plugin:
        lmp, plugin = programs.get("lmp_plugin", ""), programs.get("plugin", "")
        if not lmp or not Path(lmp).exists() or not plugin or not Path(plugin).exists():
            sys.exit("hybrid_launch: the PLUGIN-enabled LAMMPS or hybridmpmplugin.so is not built "
                     "(tools/setup.sh builds both)")
        assert wrapper_dir is not None
        wrapper = wrapper_dir / "hybrid_plugin_wrapper.lmp"
        wrapper.write_text(f"# written by tools/hybrid_launch.py --plugin\n"
                           f"plugin load {plugin}\n"
                           f"include {deck.resolve()}\n")
        lammps = [lmp, "-m", "0", "-in", str(wrapper)]
    else:
        lammps = [host, "-in", str(deck)]
    mpm_cmd = [mpm, "--coupled"]
    if args.mpm_timeout is not None:
        mpm_cmd += ["--timeout", str(args.mpm_timeout)]
    return ([str(REPO / "tools" / "mpirun.sh"), *args.mpirun_arg, "-np", str(args.np), *lammps, *args.lammps_args,
             ":", "-np", "1", *mpm_cmd])


def dem_program(args: argparse.Namespace) -> str:
    """The DEM side's program name, for messages."""
    return "liggghts_hybrid" if args.host == "liggghts" else "lmp_plugin" if args.plugin else "lmp_hybrid"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="Run LAMMPS (fix hybrid/mpm) and mpm_solver --coupled in one MPMD mpirun.",
        epilog="Arguments after the deck go to LAMMPS. Example: tools/hybrid_launch.py -np 2 "
               "input_decks/hybrid/handshake.lmp -var nsteps 1000")
    ap.add_argument("-np", "--np", type=int, default=1, help="LAMMPS ranks (default 1); mpm_solver gets 1")
    ap.add_argument("--host", choices=["lammps", "liggghts"], default="lammps",
                    help="the DEM host: lammps (lmp_hybrid, default) or liggghts (liggghts_hybrid, LIGGGHTS 3.8)")
    ap.add_argument("--plugin", action="store_true",
                    help="use the PLUGIN-enabled LAMMPS (lmp_plugin -m 0, i.e. -mpicolor 0) and plugin load "
                         "hybridmpmplugin.so instead of lmp_hybrid")
    ap.add_argument("--mpm-timeout", type=float, default=None,
                    help="seconds mpm_solver waits for the handshake (its --timeout; default 600)")
    ap.add_argument("--mpirun-arg", action="append", default=[],
                    help="extra argument for mpirun, repeatable (e.g. --mpirun-arg=--tag-output)")
    ap.add_argument("--build", type=Path, default=Path(os.environ.get("HYBRID_BUILD_DIR", REPO / "build")),
                    help="build directory (default: build/)")
    ap.add_argument("--dry-run", action="store_true", help="print the command and exit")
    ap.add_argument("deck", help="LAMMPS input deck containing fix hybrid/mpm")
    ap.add_argument("lammps_args", nargs=argparse.REMAINDER, help="passed to LAMMPS")
    args = ap.parse_args(argv)
    if args.np < 1:
        ap.error("-np must be >= 1")

    programs = load_programs(args.build)
    with tempfile.TemporaryDirectory(prefix="hybrid_launch_") as tmp:
        cmd = compose(args, programs, Path(tmp))
        if args.dry_run:
            print(shlex.join(cmd))
            return 0
        print(f"hybrid_launch: {shlex.join(cmd)}", file=sys.stderr, flush=True)
        proc = subprocess.Popen(cmd)

        def forward(signum, _frame):
            proc.send_signal(signum)   # mpirun stops the whole job on SIGINT/SIGTERM

        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, forward)
        rc = proc.wait()
    if rc != 0:
        last = args.np - 1
        lammps = "rank 0" if last == 0 else f"ranks 0-{last}"
        host = "LIGGGHTS" if args.host == "liggghts" else "LAMMPS"
        print(f"hybrid_launch: the coupled job failed (exit status {rc}); MPI_COMM_WORLD {lammps} are {host} "
              f"({dem_program(args)}), rank {args.np} is mpm_solver",
              file=sys.stderr, flush=True)
    return rc if rc >= 0 else 128 - rc


if __name__ == "__main__":
    sys.exit(main())
