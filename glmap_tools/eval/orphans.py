"""Worker processes that exit with their parent: `glmap_tools.orphans`, below both
`eval` and `ingest`, which use it; its names stay importable from here."""

from __future__ import annotations

from glmap_tools.orphans import ORPHAN_EXIT_CODE as ORPHAN_EXIT_CODE
from glmap_tools.orphans import exit_with_parent as exit_with_parent
