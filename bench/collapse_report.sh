#!/usr/bin/env bash
# bench/collapse_report.sh - the full-size error-versus-run-time report of the column collapse
# (L0 = 0.1 m, aspect 2, about 5,200 disks; every run of tools/collapse_report.py plus the
# LAMMPS-vs-LIGGGHTS noise floor); the runs go to runs/collapse_report/, the report (report.md,
# report.json, error_vs_time.png, profiles.png) to docs/results/collapse_report/. About 25
# minutes on 2 cores; an interrupted run goes on where it stopped (--resume: the outcomes saved in
# runs/collapse_report/; remove that directory for a fresh matrix).
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
"$REPO/tools/setup.sh"
# shellcheck source=/dev/null
source "$REPO/build/hybrid-env.sh"
export HYBRID_BUILD_DIR="$REPO/build" OMP_NUM_THREADS=1
# the runs (dumps, logs, HDF5 frames) stay in runs/; only the report is committed
"$HYBRID_VENV/bin/python" tools/collapse_report.py --out runs/collapse_report --width 0.1 --np 2 --liggghts --resume "$@"
mkdir -p docs/results/collapse_report
cp runs/collapse_report/{report.md,report.json,error_vs_time.png,profiles.png,kinetic_energy.png} docs/results/collapse_report/
echo "bench/collapse_report.sh: docs/results/collapse_report/"
