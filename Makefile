# servoid: everything a fresh clone needs is behind these targets.
#   make demo    create .venv, install servoid, identify the simulated servo (plots + model.json)
#                and export its compensation parameters as a C header; then identify a physical
#                twin (the XM430, the play inside its loop) live through sim://
#   make test    create .venv, install servoid with test tools, run the tests
#   make bench   run the benchmarks (tables on stdout)
#   make lint    install ruff and mypy into .venv, then lint, check the format and check the types
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
LINT_STAMP := $(VENV)/.lint-installed
# mypy must see the pillars where Python imports them (servoid.ident, ...): a tree of links
LINT_TREE  := build/lint
DEMO_OUT ?= servoid-run

.PHONY: install demo test bench lint clean

$(STAMP): pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/servoid identify --snr 43 --samples 5000 --out $(DEMO_OUT)
	$(VENV)/bin/servoid export $(DEMO_OUT)/model.json --format c --force --out $(DEMO_OUT)/backlash.h
	@echo "== a physical twin: the XM430 (encoder on the horn, the play inside the position loop), live through"
	@echo "   sim:// in simulated time, gentle sines at 40x its loop bandwidth"
	$(VENV)/bin/servoid identify --driver "sim://xm430?clock=virtual" --rate 140 --samples 5600 --no-probe \
		--excitation "gentle:amplitude=0.1,accel=0.000408,spread=8" --out $(DEMO_OUT)/xm430

test: $(STAMP)
	$(PY) -m pytest

$(LINT_STAMP): $(STAMP) pyproject.toml
	$(PY) -m pip install --quiet --disable-pip-version-check -e ".[test,lint]"
	touch $(LINT_STAMP)

lint: $(LINT_STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	rm -rf $(LINT_TREE) && mkdir -p $(LINT_TREE)/servoid
	for f in servoid/*; do ln -s "$(CURDIR)/$$f" $(LINT_TREE)/servoid/; done
	for p in ident excitation drivers; do ln -s "$(CURDIR)/$$p" $(LINT_TREE)/servoid/$$p; done
	MYPYPATH=$(LINT_TREE) $(VENV)/bin/mypy -p servoid

bench: $(STAMP)
	@for f in benchmarks/[!_]*.py; do echo "== $$f"; $(PY) $$f || exit 1; done

clean:
	rm -rf $(VENV) $(DEMO_OUT) build *.egg-info .pytest_cache
