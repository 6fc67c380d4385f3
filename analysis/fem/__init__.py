"""Solid finite elements (gmsh, scikit-fem, pyamg): generic solver, hinge release, stress."""
