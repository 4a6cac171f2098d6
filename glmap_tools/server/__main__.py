"""`python -m glmap_tools.server`: the same as the `glmap-mcp` console script."""

from glmap_tools.server.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
