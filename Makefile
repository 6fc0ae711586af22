# Two entry points on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench accuracy clean

# The C sources too: an editable install compiles them only when it runs (setup.py, cffi).
NATIVE := $(wildcard stewart_fmu/native/src/*.[ch] stewart_fmu/native/include/*.h controller/native/*.[ch])

$(STAMP): pyproject.toml setup.py $(NATIVE)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/stewart-sim demo scenes/micro_manipulator.toml --out results
	$(VENV)/bin/stewart-sim run scenes/micro_manipulator.toml --out results/run

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) benchmarks/bench_dynamics.py

accuracy: $(STAMP)
	for s in scenes/*.toml; do $(VENV)/bin/stewart-sim accuracy $$s --out results/accuracy/$$(basename $$s .toml) || exit 1; done

clean:
	rm -rf $(VENV) results build *.egg-info
