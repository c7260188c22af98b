# coobs: two-command set-up.  `make demo` and `make test` each create .venv when missing,
# install the project, make sure the system library Open3D needs is present, then run.
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.coobs-installed
OUT ?= runs

.PHONY: demo test bench lint docs syslibs install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

install: $(STAMP) syslibs

# Open3D needs libusb-1.0 at import time.  Install it with apt-get when running as root,
# otherwise print the exact command and stop.
syslibs:
	@if ! /sbin/ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
	  if [ "$$(id -u)" = "0" ]; then \
	    echo "installing libusb-1.0-0 (needed by Open3D)"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libusb-1.0-0 >/dev/null; \
	  else \
	    echo "Open3D needs the system library libusb-1.0. Run:  sudo apt-get install -y libusb-1.0-0"; \
	    exit 1; \
	  fi; \
	fi

# The most complete scenario that exists: the quickstart formation scenario when shipped,
# otherwise the exact tumbling-target truth.
demo: install
	@if [ -f experiments/configs/quickstart.toml ]; then \
	  MPLBACKEND=Agg $(BIN)/coobs run experiments/configs/quickstart.toml --out $(OUT)/quickstart; \
	else \
	  $(BIN)/coobs tumble; \
	fi

test: install
	$(BIN)/lint-imports
	MPLBACKEND=Agg $(BIN)/python -m pytest -q -p no:cacheprovider

bench: install
	$(BIN)/coobs bench --out bench.json

# The documentation site, built offline into site/ (open site/index.html); --strict turns every
# warning (a broken link or anchor, a griffe docstring warning) into a failure.
docs: install
	NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true MPLBACKEND=Agg $(BIN)/mkdocs build --strict

lint: install
	$(BIN)/ruff check .
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) $(OUT) bench.json site
