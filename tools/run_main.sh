#!/usr/bin/env bash
# tools/run_main.sh - install what is missing, build, then run the project's
# main job (the default scene with its comparison output).
# Arguments are passed to the main job. Setup output goes to stderr so that
# the job's stdout stays its own. Runs in the caller's working directory.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
MAIN_JOB="$REPO/tools/main_job.py"

"$REPO/tools/setup.sh" >&2
# shellcheck source=/dev/null
source "$REPO/build/hybrid-env.sh"

if [[ ! -f $MAIN_JOB ]]; then
  echo "run_main: ERROR: the main job $MAIN_JOB does not exist yet; nothing to run." >&2
  exit 2
fi
exec "$HYBRID_VENV/bin/python" "$MAIN_JOB" "$@"
