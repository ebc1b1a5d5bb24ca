# servoid: everything a fresh clone needs is behind these targets.
#   make demo    create .venv, install servoid, identify the simulated servo (plots + model.json)
#                and export its compensation parameters as a C header
#   make test    create .venv, install servoid with test tools, run the tests
#   make bench   run the benchmarks (tables on stdout)
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
DEMO_OUT ?= servoid-run

.PHONY: install demo test bench clean

$(STAMP): pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/servoid identify --snr 43 --samples 5000 --out $(DEMO_OUT)
	$(VENV)/bin/servoid export $(DEMO_OUT)/model.json --format c --out $(DEMO_OUT)/backlash.h

test: $(STAMP)
	$(PY) -m pytest

bench: $(STAMP)
	@for f in benchmarks/[!_]*.py; do echo "== $$f"; $(PY) $$f || exit 1; done

clean:
	rm -rf $(VENV) $(DEMO_OUT) build *.egg-info .pytest_cache
