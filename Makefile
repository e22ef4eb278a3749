# Two entry points: `make run` (the main job on the embedded default) and `make test` (the whole suite).
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
APT_CONTAINERS := apt-get install -y --no-install-recommends podman runc netavark aardvark-dns iptables uidmap \
	debootstrap openssl

.PHONY: run test test-fast check bench clean i18n

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	# torch first and exactly pinned: the CPU wheel is on disk; anything looser downloads CUDA builds.
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[worker,test]'
	# The container test (tests/integration/test_containers.py, run under CI=true) builds the images and runs the
	# compose stack with Debian's podman (runc; netavark and aardvark-dns for the stack's network and names) and a
	# debootstrap base image. Optional: without them `make run` and `make test` work, the container test skipped.
	test -x /usr/bin/podman -a -x /usr/sbin/debootstrap -a -x /usr/lib/podman/netavark || $(APT_CONTAINERS) \
		|| (apt-get update && $(APT_CONTAINERS)) || echo 'podman not installed: the container test will not run'
	# Browser tests use Debian's chromium; Playwright's own browser download is unreachable from these machines.
	test -x /usr/bin/chromium || apt-get install -y --no-install-recommends chromium \
		|| (apt-get update && apt-get install -y --no-install-recommends chromium)
	# The Chinese pages' screenshots (tests/integration/test_chinese_walk_browser.py) need one CJK font.
	test -f /usr/share/fonts/truetype/wqy/wqy-microhei.ttc || apt-get install -y --no-install-recommends fonts-wqy-microhei \
		|| (apt-get update && apt-get install -y --no-install-recommends fonts-wqy-microhei)
	touch $(STAMP)

# The embedded service (SQLite, filesystem broker, a local Celery worker): grades examples/l03/reference.yaml,
# prints the grade and the report page's URL, and keeps serving until Ctrl-C.
# `make run RUN_FLAGS=--exit-after-grading` stops once graded (scripts, CI).
RUN_FLAGS ?=
run: $(STAMP)
	$(VENV)/bin/grader run $(RUN_FLAGS)

# The suite on one test process per core (pytest-xdist; an integration module stays on one process, tests/conftest.py).
# `make test TEST_WORKERS=0` runs it in this process alone; `make test PYTEST_ARGS='tests/rubric -k tumble'` a part.
TEST_WORKERS ?= auto
PYTEST_ARGS ?=
# Each run also prints the test-process seconds per folder of tests/ (tools.suite_durations, from out/junit.xml), failed
# or not, so that CI's log says where the suite's time went (issue 43).
test: $(STAMP)
	mkdir -p out
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadgroup --no-loadscope-reorder --junitxml=out/junit.xml $(PYTEST_ARGS); \
		status=$$?; $(PY) -m tools.suite_durations out/junit.xml || true; exit $$status

# The contributor's loop: the unit and service tests, without the integration modules (real Celery workers, the
# compose stack, the browser walks) and without the tests marked slow (their own Genesis runs). `make test` stays the
# whole suite, and is what CI runs.
test-fast: $(STAMP)
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadgroup --no-loadscope-reorder -m 'not slow and not integration' \
		--ignore=tests/integration $(PYTEST_ARGS)

check: $(STAMP)
	$(VENV)/bin/grader check --backend cpu --out out/check

bench: $(STAMP)
	$(PY) -m tools.bench --out out/bench

clean:
	rm -rf out

# The pages' translations (grader/translations, grader/i18n.py): extract every _()/N_() msgid of grader/ and its
# templates into messages.pot, merge it into each language's .po (new msgids arrive empty), then list what is still
# untranslated (exit status 1 while anything is). Fill the .po's msgstr lines and run it again; no compile step:
# the app compiles the .po when it starts.
i18n: $(STAMP)
	$(VENV)/bin/pybabel extract -F babel.cfg --add-location=file --sort-by-file --project=l03-grader \
		--msgid-bugs-address= -o grader/translations/messages.pot .
	$(VENV)/bin/pybabel update -i grader/translations/messages.pot -d grader/translations -D messages \
		--no-fuzzy-matching --ignore-obsolete
	$(PY) -m grader.i18n
