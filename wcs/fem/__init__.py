"""Finite elements with scikit-fem: parameter-affine pieces, constraints, stresses."""
