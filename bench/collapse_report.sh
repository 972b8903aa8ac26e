#!/usr/bin/env bash
# bench/collapse_report.sh - the full-size error-versus-run-time reports of the column collapse at
# two aspect ratios, each with every run of tools/collapse_report.py and its 3D slab section
# (LAMMPS, LIGGGHTS, hybrid between side walls):
#   a = 2,   L0 = 0.1 m, about 5,200 disks  -> docs/results/collapse_report/
#   a = 0.5, L0 = 0.2 m, about 5,200 disks  -> docs/results/collapse_report_a0.5/
# The runs go to runs/collapse_report*/. About 25 minutes per aspect ratio on 2 cores; an
# interrupted report goes on where it stopped (--resume: the outcomes saved in its runs/
# directory; remove that directory for a fresh matrix). Arguments go to both reports; ASPECTS
# selects the reports (default "2 0.5").
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
"$REPO/tools/setup.sh"
# shellcheck source=/dev/null
source "$REPO/build/hybrid-env.sh"
export HYBRID_BUILD_DIR="$REPO/build" OMP_NUM_THREADS=1
for aspect in ${ASPECTS:-2 0.5}; do
  case "$aspect" in
    2)   width=0.1; name=collapse_report ;;
    0.5) width=0.2; name=collapse_report_a0.5 ;;
    *)   echo "bench/collapse_report.sh: no size set for aspect $aspect (2 or 0.5)" >&2; exit 2 ;;
  esac
  # the runs (dumps, logs, HDF5 frames) stay in runs/; only the report is committed
  "$HYBRID_VENV/bin/python" tools/collapse_report.py --out "runs/$name" --aspect "$aspect" --width "$width" \
    --np 2 --liggghts --resume "$@"
  mkdir -p "docs/results/$name"
  cp "runs/$name"/{report.md,report.json,error_vs_time.png,profiles.png,kinetic_energy.png} "docs/results/$name/"
  echo "bench/collapse_report.sh: docs/results/$name/"
done
