# `make demo` and `make test` bootstrap .venv from nothing (Python >= 3.11 + a Rust toolchain).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
RUST_SOURCES := $(shell find crates -name '*.rs' -o -name 'Cargo.toml') Cargo.toml
BUILT  := $(VENV)/.built

.PHONY: demo test test-rust test-python test-c lint lint-rust lint-python bench bench-c clean

$(BIN)/python:
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "Python >= 3.11 is required"'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q "maturin>=1.7,<2" "numpy>=1.26" "scipy>=1.11" "matplotlib>=3.8" "pyarrow>=14" "threadpoolctl>=3.1" "pytest>=8" "hypothesis>=6.100" "h5py>=3.10"

# The extension is rebuilt (release, LTO) whenever a Rust source changes.
$(BUILT): $(BIN)/python $(RUST_SOURCES) pyproject.toml
	VIRTUAL_ENV=$(abspath $(VENV)) $(BIN)/maturin develop --release --extras test,lint
	touch $@

demo: $(BUILT)
	$(BIN)/python -m piezohyst demo --force   # regenerates ./piezohyst-report

test: test-rust test-python test-c

# The gates CI runs before the tests: formatting, lints, strict types, the stub against the
# compiled module, and the core cross-built for a bare-metal Cortex-M4F (no_std, no allocator).
EMBEDDED_TARGET := thumbv7em-none-eabihf
PY_SOURCES := python tests bench

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

test-python: $(BUILT)
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

bench-c: $(BUILT)
	$(BIN)/python bench/c_step.py

# every benchmark in bench/ (about 6 minutes), then the summary and the README's performance section
bench: $(BUILT)
	$(BIN)/piezohyst bench --readme README.md

clean:
	rm -rf $(VENV) target
