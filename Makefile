# hapticopt — two commands for a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test bench setup clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

setup: $(STAMP)

# The main job: evaluate and export the reference 3-PRRR, then optimise → export → verify →
# report the bundled problem (outputs in cad_out/prrr-paper/ and cad_out/prrr-workspace/).
run: $(STAMP)
	$(BIN)/hapticopt evaluate --preset prrr-paper
	$(BIN)/hapticopt export --preset prrr-paper --render
	$(BIN)/hapticopt optimise prrr-workspace

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python -m pytest -q benchmarks -o python_files='bench_*.py' --benchmark-enable --benchmark-columns=min,median,max,rounds

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis .benchmarks
