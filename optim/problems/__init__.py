"""Bundled optimisation problems (TOML), loaded with :func:`optim.problem.load_problem`."""
