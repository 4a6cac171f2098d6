"""Reading the simulator's JSON files (layouts, episodes, scans) with clear errors."""

from __future__ import annotations

import json
import os
from typing import Any

from glmap_tools.errors import InvalidInputError


def read_json(path: str | os.PathLike[str], what: str, make_with: str) -> Any:
    """Parse the JSON file at `path`.

    Args:
        path: the file.
        what: what the file is, for messages ("layout file").
        make_with: how to make one, for the missing-file message ("`glmap sim new`").

    Raises:
        InvalidInputError: the file is missing, unreadable or not valid JSON.
    """
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError as exc:
        raise InvalidInputError(
            f"{what} {str(path)!r} does not exist; make one with {make_with}."
        ) from exc
    except json.JSONDecodeError as exc:
        raise InvalidInputError(f"{what} {str(path)!r} is not valid JSON: {exc}.") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"cannot read {what} {str(path)!r}: {exc}.") from exc
