"""The results folder of an evaluation: its settings, one JSON file per finished episode.

Layout of DIR::

    eval.json                          the result settings (EvalSpec.result_config) + history
    episodes/<agent>/<episode>.json    one finished episode (EpisodeResult fields + scene, config)
    summary.md, summary.json           the table of the last run
    traces/<agent>/<episode>/          tool-call traces and reports (only with --traces)
    logs/worker-K.log                  what each local worker process wrote to stderr

A rerun skips every (agent, episode) whose file exists. Settings that change a result
(`RESULT_KEYS`) must match the folder's, or the run is refused unless `mix_configs` is set;
each episode file keeps the settings it was run with, so a mixed folder stays traceable.
"""

from __future__ import annotations

import json
import math
import re
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from glmap_tools.atomic import write_atomic
from glmap_tools.checks import is_integer, is_real
from glmap_tools.errors import InvalidInputError, StoreError

CONFIG_FILE = "eval.json"
FORMAT = "glmap-eval"
VERSION = 1


def _safe(name: str) -> str:
    """A file name for an episode id: 'bench/objectnav/s03-017' -> 'bench__objectnav__s03-017'."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name.replace("/", "__"))


def write_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(data, indent=1, allow_nan=False) + "\n"
    write_atomic(path, [text.encode("utf-8")])


def finite_or_none(x: Any) -> Any:
    """JSON has no inf/NaN: such floats are stored as null."""
    return None if isinstance(x, float) and not math.isfinite(x) else x


# What the tables read of a stored record: kind -> field names (optional ones may be absent).
_RECORD_FIELDS = {
    "bool": ("success",),
    "int": ("steps", "collisions", "tool_calls", "seed"),
    "number or null": ("spl", "distance_to_goal", "path_length", "wall_s"),
}
_OPTIONAL_FIELDS = {
    "int": ("tokens", "turns"),
    "str": ("outcome", "scene", "finished_at"),
    "str or null": ("episode_key",),
    "object": ("prompts", "config"),
}


def _is_kind(value: Any, kind: str) -> bool:
    return {
        "bool": isinstance(value, bool),
        "int": is_integer(value),
        "number or null": value is None or is_real(value),
        "str": isinstance(value, str),
        "str or null": value is None or isinstance(value, str),
        "object": isinstance(value, dict),
    }[kind]


def record_problem(record: dict[str, Any]) -> str | None:
    """What makes `record` not a finished episode's record (a field missing or of another
    kind), or None."""
    for kind, names in _RECORD_FIELDS.items():
        for name in names:
            if name not in record or not _is_kind(record[name], kind):
                return f"{name} = {record.get(name)!r} is not a {kind}"
    for kind, names in _OPTIONAL_FIELDS.items():
        for name in names:
            if name in record and not _is_kind(record[name], kind):
                return f"{name} = {record[name]!r} is not a {kind}"
    return None


class ResultsDir:
    """One evaluation's results folder (see the module docstring).

    Args:
        root: the folder (created if missing).
        config: the result settings of this run.
        mix_configs: accept a folder whose settings differ (its old episodes are kept).

    Raises:
        InvalidInputError: the folder holds results of other settings and mix_configs is off,
            or its eval.json is not an evaluation's.
    """

    def __init__(self, root: Path, config: dict[str, Any], *, mix_configs: bool = False) -> None:
        self.root = Path(root)
        self.config = dict(config)
        if self.root.exists() and not self.root.is_dir():
            raise InvalidInputError(f"--out {str(self.root)!r} is a file; give a folder.")
        path = self.root / CONFIG_FILE
        if path.exists():
            stored = self._read(path)
            old = stored.get("config", {})
            changed = sorted(k for k in set(old) | set(self.config) if old.get(k) != config.get(k))
            if changed and not mix_configs:
                diffs = ", ".join(f"{k}: {old.get(k)!r} -> {config.get(k)!r}" for k in changed)
                raise InvalidInputError(
                    f"{self.root} holds results run with other settings ({diffs}); "
                    "choose another --out, or pass --mix-configs to add to them anyway."
                )
            history = list(stored.get("history", []))
        else:
            history = []
        if not history or history[-1] != self.config:
            history.append(self.config)
        self.mixed = len({json.dumps(h, sort_keys=True) for h in history}) > 1
        self.root.mkdir(parents=True, exist_ok=True)
        write_json(
            path, {"format": FORMAT, "version": VERSION, "config": config, "history": history}
        )

    @staticmethod
    def _read(path: Path) -> dict[str, Any]:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InvalidInputError(
                f"{path} is not readable JSON ({exc}); choose another --out."
            ) from exc
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise InvalidInputError(
                f"{path} is not a glmap eval file; choose another --out for the results."
            )
        history = data.get("history", [])
        if not isinstance(data.get("config", {}), dict) or not (
            isinstance(history, list) and all(isinstance(h, dict) for h in history)
        ):
            raise InvalidInputError(
                f"{path} has a 'config' that is not an object or a 'history' that is not a "
                "list of them; restore the file, or choose another --out for the results."
            )
        return data

    def episode_path(self, agent: str, episode_id: str) -> Path:
        return self.root / "episodes" / agent / f"{_safe(episode_id)}.json"

    def trace_dir(self, agent: str, episode_id: str) -> Path:
        return self.root / "traces" / agent / _safe(episode_id)

    def load(self, agent: str, episode_id: str) -> dict[str, Any] | None:
        """The stored record of a finished episode, or None (also for an unreadable file or
        one whose fields are not an episode's: the episode is then played again)."""
        path = self.episode_path(agent, episode_id)
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        ok = isinstance(record, dict) and record.get("episode_id") == episode_id
        ok = ok and record.get("agent") == agent and record_problem(record) is None
        return record if ok else None

    def save(self, record: dict[str, Any]) -> dict[str, Any]:
        """Write one finished episode atomically (a crash leaves the old file or none).

        Returns:
            the record as stored (non-finite floats as None, settings and time added).
        """
        for key in ("agent", "episode_id"):
            if not isinstance(record.get(key), str):
                raise StoreError(f"episode record lacks {key!r}: {record!r}")
        clean = {k: finite_or_none(v) for k, v in record.items()}
        clean.setdefault("config", self.config)
        clean.setdefault("finished_at", datetime.now(UTC).isoformat(timespec="seconds"))
        path = self.episode_path(record["agent"], record["episode_id"])
        write_json(path, clean)
        return clean
