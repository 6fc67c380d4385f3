"""Bundled optimisation problems (TOML), loaded with :func:`hapticopt.optim.problem.load_problem`."""
