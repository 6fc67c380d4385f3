"""Evaluators, firmware, plants and plots of the 3-PRRR (seed 002)."""
