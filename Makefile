# Every target creates the virtual environment and installs xval into it when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
XVAL := $(VENV)/bin/xval
STAMP := $(VENV)/.installed-stamp
JOBS ?= 2

.PHONY: demo test bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(PY) -m compare.demo

test: $(STAMP)
	$(PY) -m pytest -n $(JOBS) -q

bench: $(STAMP)
	@for script in bench/bench_*.py; do echo "== $$script"; $(PY) $$script || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info results artifacts
