# hapticopt — two commands for a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint hardcases bench setup clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[dev]"
	$(BIN)/python -m hapticopt.analysis.warmup
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

# ruff with the rule set of pyproject.toml's [tool.ruff] (mistakes, not style); .ci/run runs it first.
lint: $(STAMP)
	$(BIN)/ruff check design analysis optim tests benchmarks scripts

# Verdicts near singularities and thresholds (pytest -m hardcase) under two OpenBLAS kernels:
# a verdict that flips with the BLAS kernel is a rounding-level threshold (issue 14).
# Haswell (AVX2) and Prescott (SSE3; OpenBLAS reports it as Katmai) both load on x86-64.
OPENBLAS_KERNELS ?= Haswell Prescott
hardcases: $(STAMP)
	@for k in $(OPENBLAS_KERNELS); do \
		echo "hard cases under OPENBLAS_CORETYPE=$$k"; \
		OPENBLAS_CORETYPE=$$k $(BIN)/python -m pytest -q -m hardcase || exit 1; \
	done

bench: $(STAMP)
	$(BIN)/python -m pytest -q benchmarks -o python_files='bench_*.py' --benchmark-enable --benchmark-columns=min,median,max,rounds

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis .benchmarks
