PYTHON ?= .venv/bin/python
LINT_PATHS = sb3_saeir/ tests/ examples/ benchmarks/

.PHONY: install test pytest test-slow lint format check-codestyle type missing-annotations commit-checks quickstart docs docs-linkcheck ci clean

install:
	bash scripts/install.sh tests,zoo,plots,ray,docs

pytest test:
	$(PYTHON) -m pytest -n 2 -q

test-slow:
	$(PYTHON) -m pytest -m slow -q -s

lint:
	$(PYTHON) -m ruff check $(LINT_PATHS)

format:
	$(PYTHON) -m ruff check --fix $(LINT_PATHS)
	$(PYTHON) -m ruff format $(LINT_PATHS)

check-codestyle:
	$(PYTHON) -m ruff format --check $(LINT_PATHS)

type:
	$(PYTHON) -m mypy sb3_saeir benchmarks examples

missing-annotations:
	$(PYTHON) -m mypy --disallow-untyped-defs --ignore-missing-imports sb3_saeir benchmarks examples

commit-checks: format type lint

quickstart:
	bash scripts/quickstart.sh

# The documentation site (needs the docs extra): warnings are errors; then internal links (external ones are skipped).
docs:
	$(PYTHON) -m sphinx -W --keep-going -q -b html docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

docs-linkcheck:
	$(PYTHON) -m sphinx -W --keep-going -q -b linkcheck docs docs/_build/linkcheck

ci:
	bash .ci/run

clean:
	rm -rf .mypy_cache .ruff_cache .pytest_cache build dist *.egg-info docs/_build
