"""Worlds for the simulator: generated apartments and houses, scans made into layouts, and
the data sets drawn from them (the benchmark splits, scene folders, QA sets, tours).

`glmap_tools.sim` is the environment a layout is played in; this package makes the layouts
and the episode files, and sits above it (a split builds its env; a QA set walks its
situations with the env's motion). `glmap sim ...` is `cli.py` here.
"""
