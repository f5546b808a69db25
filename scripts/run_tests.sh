#!/usr/bin/env bash
# The README's test command: set up .venv with the test and docs extras, lint, type check, build the docs, then run the
# default (not slow) tests.
# Usage: bash scripts/run_tests.sh [extra pytest arguments]
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh tests,zoo,plots,ray,docs || { echo "install failed"; exit 1; }
bash scripts/install_postgres.sh || { echo "PostgreSQL install failed (needed by the distributed tuning test)"; exit 1; }
bash scripts/install_football.sh || { echo "gfootball install failed (needed by the football tests)"; exit 1; }
echo "== ruff"
.venv/bin/ruff check sb3_saeir tests examples benchmarks || { echo "lint errors (ruff check) - fix them or run 'make format'"; exit 1; }
echo "== mypy"
.venv/bin/mypy sb3_saeir benchmarks examples || { echo "type errors (mypy) - see above"; exit 1; }
echo "== docs (sphinx, warnings as errors; internal links)"
.venv/bin/python -m sphinx -W --keep-going -q -b html docs docs/_build/html \
    || { echo "docs build failed: Sphinx warnings above (make docs reproduces them)"; exit 1; }
.venv/bin/python -m sphinx -W --keep-going -q -b linkcheck docs docs/_build/linkcheck \
    || { echo "docs link check failed: broken internal links above (make docs-linkcheck reproduces them)"; exit 1; }
echo "== pytest"
.venv/bin/python -m pytest -n 2 -q "$@"
status=$?
case $status in
    0) echo "tests passed" ;;
    5) echo "pytest collected no tests: treated as a failure"; status=1 ;;
    *) echo "pytest failed with exit code $status" ;;
esac
exit $status
