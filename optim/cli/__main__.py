"""``python -m hapticopt.optim.cli``: the same entry point as the ``hapticopt`` script."""

from hapticopt.optim.cli import main

if __name__ == "__main__":
    main()
