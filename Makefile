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
	touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/grader run --exit-after-grading

test: $(STAMP)
	$(PY) -m pytest

check: $(STAMP)
	$(VENV)/bin/grader check --backend cpu --out out/check

bench: $(STAMP)
	$(VENV)/bin/grader bench --out out/bench

clean:
	rm -rf out
