#!/usr/bin/env bash
# The README's test command: set up .venv with the test extras, lint, then run the default (not slow) tests.
# Usage: bash scripts/run_tests.sh [extra pytest arguments]
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh tests,zoo,plots,ray || { echo "install failed"; exit 1; }
bash scripts/install_postgres.sh || { echo "PostgreSQL install failed (needed by the distributed tuning test)"; exit 1; }
bash scripts/install_football.sh || { echo "gfootball install failed (needed by the football tests)"; exit 1; }
echo "== ruff"
.venv/bin/ruff check sb3_saeir tests examples benchmarks || { echo "lint errors (ruff check) - fix them or run 'make format'"; exit 1; }
echo "== mypy"
.venv/bin/mypy sb3_saeir || { echo "type errors (mypy) - see above"; exit 1; }
echo "== pytest"
.venv/bin/python -m pytest -n 2 -q "$@"
status=$?
case $status in
    0) echo "tests passed" ;;
    5) echo "pytest collected no tests: treated as a failure"; status=1 ;;
    *) echo "pytest failed with exit code $status" ;;
esac
exit $status
