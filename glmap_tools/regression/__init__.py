"""Checks that a change keeps behaviour: `python -m glmap_tools.regression.replay`."""
