#!/usr/bin/env bash
# tools/run_tests.sh - install what is missing, build, run the whole test suite:
# the C++ tests (ctest) and the Python tests (pytest, in the project venv).
# Both suites always run and print their summaries; the exit status is non-zero
# if either fails. pytest's exit code 5 (no tests collected) counts as a failure.
# Extra arguments are passed to pytest (e.g. tools/run_tests.sh -k collapse).
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"

"$REPO/tools/setup.sh"
# shellcheck source=/dev/null
source "$REPO/build/hybrid-env.sh"

echo "run_tests: ctest"
ctest_rc=0
ctest --test-dir build --output-on-failure --no-tests=error || ctest_rc=$?

echo "run_tests: pytest"
pytest_rc=0
"$HYBRID_VENV/bin/python" -m pytest tests -v "$@" || pytest_rc=$?

echo "run_tests: ctest exit status $ctest_rc, pytest exit status $pytest_rc"
if [[ $pytest_rc -eq 5 ]]; then
  echo "run_tests: pytest collected no tests - counted as a failure" >&2
fi
if [[ $ctest_rc -ne 0 || $pytest_rc -ne 0 ]]; then
  echo "run_tests: FAILED" >&2
  exit $(( ctest_rc != 0 ? ctest_rc : pytest_rc ))
fi
echo "run_tests: all passed"
