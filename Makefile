# Two entry points on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-numerics docs bench accuracy clean system-packages

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

test: $(STAMP) system-packages
	$(PY) -m pytest -q -n auto --dist loadfile

# The tests whose result an optimiser, a threshold or a convergence decides (marker `numerics`)
# again in a second floating-point environment: one BLAS thread instead of one per core, and
# another OpenBLAS kernel that this CPU runs (tools/second_blas_kernel.sh), so BLAS adds in
# another order. CI runs it after `test`.
test-numerics: $(STAMP)
	kernel=$$(sh tools/second_blas_kernel.sh); echo "OPENBLAS_NUM_THREADS=1 OPENBLAS_CORETYPE=$$kernel"; \
	OPENBLAS_NUM_THREADS=1 OPENBLAS_CORETYPE=$$kernel $(PY) -m pytest -q -n auto --dist loadfile -m numerics

# The documentation site (docs/, Sphinx: docs/why-sphinx.md) into docs/_build/html, from a clean
# build every time, every warning an error (-W; --keep-going reports them all first). The `docs`
# extra goes into the same .venv, which the API reference needs (autodoc imports the packages).
DOCS_STAMP := $(VENV)/.docs-installed

$(DOCS_STAMP): pyproject.toml setup.py $(NATIVE)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	rm -rf docs/_build
	$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html
	@echo "docs/_build/html/index.html"

# Debian packages the tests use, as command:package: mingw-w64's C compiler (export-fmu's
# Windows DLL; stewart_fmu/fmu/windows.py) and wine (runs it). Installed with apt-get, without
# their recommends (~160 MB, ~30 s), when we run as root and they are missing; elsewhere the
# FMU has no Windows binary and the tests that need one are skipped, saying why.
SYSTEM_PACKAGES := x86_64-w64-mingw32-gcc:gcc-mingw-w64-x86-64-win32 wine:wine

system-packages:
	@missing=""; for pair in $(SYSTEM_PACKAGES); do \
	  command -v $${pair%%:*} >/dev/null 2>&1 || missing="$$missing $${pair#*:}"; done; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if [ "$$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then \
	  echo "not installed:$$missing (not root with apt-get): the Windows FMU tests are skipped"; exit 0; fi; \
	echo "apt-get install$$missing"; \
	export DEBIAN_FRONTEND=noninteractive; \
	apt-get update -qq && apt-get install -y -qq --no-install-recommends $$missing >/dev/null

bench: $(STAMP)
	$(PY) benchmarks/bench_dynamics.py

accuracy: $(STAMP)
	for s in scenes/*.toml; do $(VENV)/bin/stewart-sim accuracy $$s --out results/accuracy/$$(basename $$s .toml) || exit 1; done

clean:
	rm -rf $(VENV) results build *.egg-info docs/_build docs/reference/generated
