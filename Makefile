# Two entry points: `make run` (the main job on the embedded default) and `make test` (the whole suite).
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: run test check bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	# torch first and exactly pinned: the CPU wheel is on disk; anything looser downloads CUDA builds.
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[test]'
	# Browser tests use Debian's chromium; Playwright's own browser download is unreachable from these machines.
	test -x /usr/bin/chromium || apt-get install -y --no-install-recommends chromium \
		|| (apt-get update && apt-get install -y --no-install-recommends chromium)
	touch $(STAMP)

# The embedded service (SQLite, filesystem broker, a local Celery worker): grades examples/l03/reference.yaml,
# prints the grade and the report page's URL, and keeps serving until Ctrl-C.
# `make run RUN_FLAGS=--exit-after-grading` stops once graded (scripts, CI).
RUN_FLAGS ?=
run: $(STAMP)
	$(VENV)/bin/grader run $(RUN_FLAGS)

test: $(STAMP)
	$(PY) -m pytest

check: $(STAMP)
	$(VENV)/bin/grader check --backend cpu --out out/check

bench: $(STAMP)
	$(PY) -m tools.bench --out out/bench

clean:
	rm -rf out
