"""Seed 001's controllers (issue 18): the eq 2 human model, the iterative optimal impedance
outer loop (IOIC: LQR optimum, off-policy policy iteration from data, soft switch) and the
nonsingular terminal sliding-mode inner loop (NTSMTC) on the paper's two-link arm.

Self-contained: imports only numpy, scipy and jax. SI units throughout.
"""
