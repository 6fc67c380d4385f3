"""Evaluators, firmware controllers, plants and scenes of hapticopt.

Shared physics sits here (``fidelity``, ``status``, ``interference``, ``fem/``, ``loop/``), one
folder per device above it (``prrr/``, ``master/``), and ``registry`` / ``verify`` on top; see
docs/architecture.md for the import rule.
"""
