# Every target creates the virtual environment and installs xval into it when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
XVAL := $(VENV)/bin/xval
STAMP := $(VENV)/.installed-stamp
JOBS ?= 2
# Exact versions of every dependency (extras test, all and lint), generated from pyproject.toml by `make lock`.
LOCK := requirements.lock
LOCK_EXTRAS := --extra test --extra all --extra lint

.PHONY: demo stiff test lint lock upgrade bench bench-all baseline clean examples history-demo

# The venv from the lock file (no resolution: a fresh clone gets the versions the baselines and the docs'
# figures were made with), then xval and the example plug-in on top without touching those versions.
$(STAMP): $(LOCK) pyproject.toml examples/my-solver/pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r $(LOCK)
	$(PY) -m pip install --quiet --no-deps -e . -e examples/my-solver
	touch $(STAMP)

# Regenerate the lock from pyproject.toml (run it after adding or changing a dependency, and commit both).
# uv resolves for Python 3.11 on this platform (CI's: Linux x86_64); versions already locked are kept where they fit.
UV := $(VENV)/bin/uv
UV_COMPILE := $(UV) pip compile pyproject.toml $(LOCK_EXTRAS) --python-version 3.11 --quiet
$(UV):
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet uv

lock: | $(UV)
	$(UV_COMPILE) --output-file $(LOCK)

# Newest versions of everything, and the self-gate's baseline remade with them, in one step: review both diffs.
upgrade: | $(UV)
	$(UV_COMPILE) --upgrade --output-file $(LOCK)
	$(MAKE) $(STAMP)
	$(MAKE) baseline

# ruff (pyflakes, bugbear and syntax rules) and mypy, configured in pyproject.toml; .ci/run runs it before the tests.
lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

demo: $(STAMP)
	$(PY) -m compare.demo
	$(XVAL) report results/default

# Hard cases (suites/stiff.toml): the suite, the stability search and the Baumgarte gain map into
# results/stiff (replaced), then its report. A few minutes on 2 cores; docs/findings.md quotes it.
stiff: $(STAMP)
	rm -rf results/stiff
	$(XVAL) run suites/stiff.toml --output results/stiff --jobs $(JOBS)
	$(XVAL) stability suites/stiff.toml --output results/stiff --jobs $(JOBS)
	$(XVAL) report results/stiff

# -rs: every skip and its reason are printed (XVAL_CI=1, as .ci/run sets, makes a skip a failure).
# --dist loadgroup: tests marked with one xdist_group run in one worker (a kernel compiled once, not per worker).
test: $(STAMP)
	$(PY) -m pytest -n $(JOBS) --dist loadgroup -q -rs

# ours against its yardsticks and peers: one table, and results/bench/bench_ours.json; then ours' rigid
# bodies: N-scaling on chains and the KUKA against MuJoCo (results/bench/bench_rigid.json); then every
# engine's own stepper on the KUKA model scene, per step against MuJoCo's (a table; every engine installed).
bench: $(STAMP)
	$(PY) bench/bench_ours.py
	$(PY) bench/bench_rigid.py
	$(PY) bench/bench_models.py

bench-all: $(STAMP)
	@# bench_file_create last: the files it deletes would make the next script's record files dearer (bench/README.md)
	@for script in $$(ls bench/bench_*.py | grep -v bench_file_create) bench/bench_file_create.py; do \
		echo "== $$script"; $(PY) $$script || exit 1; done

# Regenerate the self-gate's baseline (tests/test_self_gate.py gates suites/smoke.toml against it).
# Run it after a deliberate change of accuracy or of the smoke suite, and commit baselines/smoke.json.
baseline: $(STAMP)
	@mkdir -p baselines
	@dir=$$(mktemp -d) && $(XVAL) run suites/smoke.toml --output $$dir/smoke > /dev/null \
		&& $(XVAL) baseline $$dir/smoke --output baselines/smoke.json; \
		status=$$?; rm -rf $$dir; exit $$status

# The project's own accuracy story (not part of make test): suites/smoke.toml at each of the last
# HISTORY_COMMITS commits, each in a temporary git worktree with its own virtual environment (asv-style),
# into results/history-demo/history.sqlite, then its trend page results/history-demo/trend.html.
# A few minutes per commit; commits already in the history are not run again.
HISTORY_COMMITS ?= 4
history-demo: $(STAMP)
	$(PY) scripts/history_demo.py --commits $(HISTORY_COMMITS) --jobs $(JOBS) \
		--history results/history-demo/history.sqlite --output results/history-demo/trend.html

# The C++ example solvers of the process protocol (docs/protocol.md), built with g++ into examples/cpp/build.
examples:
	$(MAKE) -C examples/cpp

clean:
	$(MAKE) -C examples/cpp clean
	rm -rf $(VENV) build *.egg-info results artifacts
