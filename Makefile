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
# report the bundled problem (outputs in cad_out/prrr-paper/ and cad_out/prrr-workspace/). A second
# `make run` resumes the recorded run (every point replayed) instead of being refused.
run: $(STAMP)
	$(BIN)/hapticopt evaluate --preset prrr-paper
	$(BIN)/hapticopt export --preset prrr-paper --render
	$(BIN)/hapticopt optimise prrr-workspace $(if $(wildcard cad_out/prrr-workspace/evaluations.sqlite),--resume,)

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python -m pytest -q benchmarks -o python_files='bench_*.py' --benchmark-enable --benchmark-columns=min,median,max,rounds

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis .benchmarks
