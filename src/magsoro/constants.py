"""Physical constants of the package (SI units)."""

MU0 = 1.25663706212e-6
"""Vacuum permeability mu0, T m / A (CODATA 2018)."""
