# `make demo` and `make test` bootstrap .venv from nothing (Python >= 3.11 + a Rust toolchain).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
RUST_SOURCES := $(shell find crates -name '*.rs' -o -name 'Cargo.toml') Cargo.toml
BUILT  := $(VENV)/.built

.PHONY: demo readme-demo test test-rust test-python test-c lint lint-rust lint-python bench bench-c clean wheel-check docs docs-check docs-browser-deps

$(BIN)/python:
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "Python >= 3.11 is required"'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q "maturin>=1.7,<2" "numpy>=1.26" "scipy>=1.11" "matplotlib>=3.8" "pyarrow>=14" "control>=0.10.1" "threadpoolctl>=3.1" "tqdm>=4.66" "dask[distributed]>=2024.8" "pytest>=8" "hypothesis>=6.100" "h5py>=3.10" "numpydoc==1.11.0" "slycot>=0.6" "pandas>=2.1"

# The extension is rebuilt (release, LTO) whenever a Rust source changes.
$(BUILT): $(BIN)/python $(RUST_SOURCES) pyproject.toml
	VIRTUAL_ENV=$(abspath $(VENV)) $(BIN)/maturin develop --release --extras test,lint
	touch $@

# The package's bytecode, compiled again when a source changes. An editable install writes none, and
# a shell with PYTHONDONTWRITEBYTECODE=1 never does: every command would then compile the package's
# modules at start (piezohyst simulate of an FSM test record with its 120-state model, by hand:
# 0.63-0.69 s without, 0.36-0.40 s with). compileall writes them whatever that variable says;
# imports read them either way.
BYTECODE   := $(VENV)/.bytecode
PY_PACKAGE := $(shell find python/piezohyst -name '*.py')
$(BYTECODE): $(BUILT) $(PY_PACKAGE)
	$(BIN)/python -m compileall -q python/piezohyst
	touch $@

demo: $(BYTECODE)
	$(BIN)/python -m piezohyst demo --force   # regenerates ./piezohyst-report

# the README's demo section from a full run (seed 0), and the run's numbers kept beside the
# benchmarks' (tests/papers/test_demo_readme.py checks that the README equals them)
readme-demo: $(BYTECODE)
	$(BIN)/python -m piezohyst demo --force --seed 0 --readme README.md
	cp piezohyst-report/results.json bench/results/demo_results.json

test: test-rust test-python test-c

# The gates CI runs before the tests: formatting, lints, strict types, the stub against the
# compiled module, and the core cross-built for a bare-metal Cortex-M4F (no_std, no allocator).
EMBEDDED_TARGET := thumbv7em-none-eabihf
PY_SOURCES := python tests bench examples docs build_backend

lint: lint-rust lint-python

lint-rust:
	cargo fmt --all --check
	cargo clippy --workspace --all-targets -- -D warnings
	rustup target list --installed | grep -qx $(EMBEDDED_TARGET) || rustup target add $(EMBEDDED_TARGET)
	cargo clippy -p piezohyst-core --target $(EMBEDDED_TARGET) -- -D warnings
	cargo build -p piezohyst-core --release --target $(EMBEDDED_TARGET)

lint-python: $(BUILT)
	$(BIN)/ruff check $(PY_SOURCES)
	$(BIN)/ruff format --check $(PY_SOURCES)
	$(BIN)/mypy
	$(BIN)/python -m mypy.stubtest piezohyst._core

test-rust:
	cargo build -p piezohyst-core            # no_std: the core without its std feature
	cargo test -p piezohyst-core

test-python: $(BYTECODE)
	$(BIN)/python -m pytest

# The C library (crates/capi): static + shared library, its Rust tests (counting allocator,
# fuzz, header freshness), shared vectors Python generates and C replays, bad input from C.
CC       ?= cc
C_DIR    := target/c-test
C_FLAGS  := -std=c99 -O2 -Wall -Wextra -Werror -pedantic -ffp-contract=off -Icrates/capi/include
C_LIBS   := -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc
CAPI_LIB := target/release/libpiezohyst.a

test-c: $(BUILT)
	cargo build --release -p piezohyst-capi
	cargo test -p piezohyst-capi
	mkdir -p $(C_DIR)
	$(BIN)/python tests/c/gen_vectors.py $(C_DIR)/vectors.txt
	$(CC) $(C_FLAGS) tests/c/replay_vectors.c $(CAPI_LIB) $(C_LIBS) -o $(C_DIR)/replay_vectors
	$(CC) $(C_FLAGS) tests/c/bad_input.c -Ltarget/release -lpiezohyst -Wl,-rpath,$(abspath target/release) -lm -o $(C_DIR)/bad_input
	$(C_DIR)/replay_vectors $(C_DIR)/vectors.txt
	@# a refused call prints nothing: bad_input's stderr must stay empty (no Rust backtrace)
	$(C_DIR)/bad_input 2>$(C_DIR)/bad_input.stderr || { cat $(C_DIR)/bad_input.stderr; exit 1; }
	@test ! -s $(C_DIR)/bad_input.stderr || { echo "bad_input wrote to stderr:"; cat $(C_DIR)/bad_input.stderr; exit 1; }
	@# the docs' C example (docs/guides/export_c.rst) compiles against the header and library and runs
	$(CC) $(C_FLAGS) examples/c/pi_inverse.c -Ltarget/release -lpiezohyst -Wl,-rpath,$(abspath target/release) -lm -o $(C_DIR)/pi_inverse
	$(C_DIR)/pi_inverse

# The wheel as pip builds it (`pip wheel .`, through build_backend/piezohyst_build.py): it ships
# libpiezohyst (.so and .a) and piezohyst.h; `python -m piezohyst.capi --cflags --libs` run from
# the wheel's files points into them; the docs' C example compiles against them alone and runs.
# About 2.5 minutes on the 2-core machine (the extension's release build with LTO).
WHEEL_DIR := target/wheel-check
wheel-check: $(BUILT)
	rm -rf $(WHEEL_DIR)
	$(BIN)/python -m pip wheel . -w $(WHEEL_DIR) --no-deps -q
	$(BIN)/python tests/c/check_wheel.py $(WHEEL_DIR)

bench-c: $(BYTECODE)
	$(BIN)/python bench/c_step.py

# every benchmark in bench/ (about 6 minutes), then the summary and the README's performance section
bench: $(BYTECODE)
	$(BIN)/piezohyst bench --readme README.md

# The documentation site (docs/, examples/): the `docs` extra of pyproject.toml is installed into
# .venv once; the build itself downloads nothing (no intersphinx, MathML written at build time),
# runs the example gallery, and fails on any warning. Open docs/_build/html/index.html.
DOCS_BUILT := $(VENV)/.docs-built
DOCS_OUT   := docs/_build/html

$(DOCS_BUILT): $(BUILT) pyproject.toml
	$(BIN)/python -c 'import tomllib; print("\n".join(tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["docs"]))' > $(VENV)/docs-requirements.txt
	$(BIN)/python -m pip install -q -r $(VENV)/docs-requirements.txt
	touch $@

docs: $(DOCS_BUILT)
	rm -rf $(DOCS_OUT) docs/api/generated docs/gallery docs/sg_execution_times.rst
	MPLBACKEND=Agg $(BIN)/python -m sphinx -W --keep-going -q -b html docs $(DOCS_OUT)

# Chromium from Debian's packages, for the browser checks (a no-op where it is installed)
docs-browser-deps:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
		{ apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; }

# the built site in headless Chromium: its index and a gallery page show their figures
docs-check: docs-browser-deps
	PIEZOHYST_DOCS_REQUIRED=1 $(BIN)/python -m pytest tests/test_docs_site.py -p no:cacheprovider

clean:
	rm -rf $(VENV) target docs/_build docs/api/generated docs/gallery && find python -name __pycache__ -type d -prune -exec rm -rf {} +
