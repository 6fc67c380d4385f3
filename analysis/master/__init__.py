"""Evaluators, firmware, plants and plots of the surgical master (seed 003)."""
