"""Benchmarks: `python -m glmap_tools.bench NAME` prints figures and ratios."""
