"""One hierarchy for every user-facing failure; each message names the bad value and the fix."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class GLMapError(Exception):
    """Base of every error glmap-tools raises on purpose."""


class InvalidInputError(GLMapError, ValueError):
    """An argument (image, pose, intrinsics, mask, annotation) is malformed."""


class UnknownIdError(GLMapError, KeyError):
    """A unit id, map name or other key does not exist."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class StoreError(GLMapError):
    """A map file cannot be opened, read or written."""


class LimitError(GLMapError):
    """A call would take the server past one of its documented limits (memory held, ...)."""


def did_you_mean(bad: str, choices: Iterable[str]) -> str:
    """Return ' Did you mean X?' for the closest choice, or '' when none is close."""
    close = difflib.get_close_matches(str(bad), [str(c) for c in choices], n=1, cutoff=0.5)
    return f" Did you mean {close[0]!r}?" if close else ""


class LLMError(GLMapError):
    """A language-model backend failed (unreachable, missing model, timeout, bad output)."""


class LLMUnavailableError(LLMError):
    """The model server cannot be reached or the model is not installed there."""


class LLMOutputError(LLMError):
    """The model's reply does not fit what was asked for, even after a retry."""


class ReplayMissError(LLMError):
    """A recorded transcript holds no response for this request."""


class NoMatchError(GLMapError):
    """A text matches nothing in the map well enough to act on (the best candidates are listed)."""
