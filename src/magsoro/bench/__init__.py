"""Benchmarks: fixed scenes, a bare reference MPM step, and the runner behind ``magsoro bench``."""
