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


# A suggestion must be close: difflib's ratio (2 x matched characters / total) at least
# this, or a single typo (one insertion, deletion or substitution). Unrelated words of
# similar letters stay under it (blanket/plant 0.67, candle/cabinet 0.62, vase/washer 0.60,
# clock/couch 0.60, camera/chair 0.55, pot/poster 0.67) while typos pass (chiar/chair 0.80,
# tabel/table 0.80, frontir/frontier 0.93, 40/4 one deletion).
CLOSE_RATIO = 0.75


def _edits(a: str, b: str) -> int:
    """Levenshtein distance (insertions, deletions, substitutions)."""
    prev = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        cur = [i]
        for j, cb in enumerate(b, 1):
            cur.append(min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (ca != cb)))
        prev = cur
    return prev[-1]


def _one_typo(a: str, b: str) -> bool:
    """One insertion or deletion ('40' for '4'), or one substitution in a word of 4+
    letters ('rug' is not a typo of 'mug')."""
    if not a or not b or _edits(a, b) != 1:
        return False
    return len(a) != len(b) or len(a) >= 4


def closest(bad: str, choices: Iterable[str]) -> str | None:
    """The choice closest to `bad` (case ignored) when it is close (`CLOSE_RATIO`, or one
    typo away), else None."""
    key = str(bad).lower()
    best: tuple[float, str] | None = None
    for c in dict.fromkeys(str(c) for c in choices):
        low = c.lower()
        ratio = difflib.SequenceMatcher(None, key, low).ratio()
        if ratio < CLOSE_RATIO and not _one_typo(key, low):
            continue
        # Ties as difflib.get_close_matches breaks them: the larger string.
        if best is None or (ratio, c) > best:
            best = (ratio, c)
    return best[1] if best is not None else None


def did_you_mean(bad: str, choices: Iterable[str]) -> str:
    """Return ' Did you mean X?' for the closest choice, or '' when none is close
    (`closest`: a word that would relabel a thing, blanket -> plant, is no suggestion)."""
    close = closest(bad, choices)
    return f" Did you mean {close!r}?" if close is not None else ""


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
