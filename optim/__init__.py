"""Optimisation problems, the NLopt driver, the recorder, the pipeline and the CLI."""
