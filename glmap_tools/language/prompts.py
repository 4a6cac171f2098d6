"""Prompts as plain text files with `str.format` placeholders, loaded by one helper.

The files live in the repository's top-level `prompts/` folder; `glmap_tools/prompts` is a
symbolic link to it, so the package data and the folder people edit are one source (a test
checks that a built wheel carries the same bytes). Every prompt has a name (its file stem)
and a content hash, written into every transcript, so an answer can be traced to the exact
prompt text that produced it. A `--prompts DIR` folder overrides prompts by file name;
prompts it does not hold come from the package.
"""

from __future__ import annotations

import hashlib
import os
import string
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

from glmap_tools.errors import InvalidInputError, UnknownIdError, did_you_mean

SUFFIX = ".txt"
MAX_PROMPT_BYTES = 64_000


@dataclass(frozen=True)
class Prompt:
    """One prompt template.

    Attributes:
        name: file stem, e.g. "unit_value_instance".
        text: the template, with `str.format` placeholders ({goal}; literal braces doubled).
        sha256: hex digest of the UTF-8 text (first 12 characters in `ref`).
        source: where it was read from.
    """

    name: str
    text: str
    sha256: str
    source: str

    @property
    def ref(self) -> str:
        """`name@hash12`: the prompt's identity in transcripts and tables."""
        return f"{self.name}@{self.sha256[:12]}"

    @property
    def fields(self) -> frozenset[str]:
        """The placeholder names the template uses."""
        return frozenset(
            field.split(".")[0].split("[")[0]
            for _, field, _, _ in string.Formatter().parse(self.text)
            if field
        )

    def format(self, **values: object) -> str:
        """Fill the placeholders.

        Raises:
            InvalidInputError: a placeholder without a value or a value without a placeholder
                (a prompt edited out of step with the code that fills it).
        """
        missing = sorted(self.fields - values.keys())
        extra = sorted(values.keys() - self.fields)
        if missing or extra:
            raise InvalidInputError(
                f"prompt {self.name!r} ({self.source}) does not fit its caller: "
                f"placeholders without a value {missing}, values without a placeholder "
                f"{extra}. Keep the file's {{placeholders}} to {sorted(values)} "
                "(write literal braces as {{ and }})."
            )
        return self.text.format(**values)


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def package_prompts_dir() -> Path:
    """The prompts folder installed with the package."""
    return Path(str(resources.files("glmap_tools") / "prompts"))


def _read(path: Path, name: str) -> Prompt:
    size = path.stat().st_size
    if size > MAX_PROMPT_BYTES:
        raise InvalidInputError(
            f"prompt file {path} is {size} bytes; prompts are limited to {MAX_PROMPT_BYTES}."
        )
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InvalidInputError(f"prompt file {path} is not UTF-8 text: {exc}.") from None
    check_template(text, str(path))
    return Prompt(name, text, _digest(text), str(path))


def check_template(text: str, source: str) -> None:
    """Refuse a template `str.format` cannot fill or whose placeholders are more than a name.

    Raises:
        InvalidInputError: naming the file, what is wrong and how to write it.
    """
    fix = "placeholders are a name in braces, e.g. {goal}; write literal braces as {{ and }}"
    try:
        parts = list(string.Formatter().parse(text))
    except ValueError as exc:
        raise InvalidInputError(f"prompt file {source}: {exc}; {fix}.") from None
    for _, field, spec, conversion in parts:
        if field is None:
            continue
        if not field.isidentifier() or spec or conversion:
            shown = field + (f"!{conversion}" if conversion else "") + (f":{spec}" if spec else "")
            raise InvalidInputError(f"prompt file {source} has the placeholder {{{shown}}}; {fix}.")


class PromptSet:
    """Prompts by name: an override folder first, then the package's prompts.

    Args:
        override: a folder of `<name>.txt` files (the `--prompts DIR` option), or None.

    Raises:
        InvalidInputError: `override` is not a folder, or a prompt file in it is too large, not
            UTF-8, or not a template (`check_template`).
    """

    def __init__(self, override: str | os.PathLike[str] | None = None) -> None:
        self.override = Path(override).expanduser() if override is not None else None
        if self.override is not None and not self.override.is_dir():
            raise InvalidInputError(
                f"--prompts {str(override)!r} is not a folder; give a folder of <name>.txt "
                f"prompt files (copy {package_prompts_dir()} to start from the defaults)."
            )
        self._cache: dict[str, Prompt] = {}
        if self.override is not None:  # refuse a bad prompt file now, not at its first use
            known = {p.stem for p in package_prompts_dir().glob(f"*{SUFFIX}")}
            for path in sorted(self.override.glob(f"*{SUFFIX}")):
                if path.stem in known and path.is_file():
                    _read(path, path.stem)

    def names(self) -> list[str]:
        """Every prompt name available (package and override)."""
        found = {p.stem for p in package_prompts_dir().glob(f"*{SUFFIX}")}
        if self.override is not None:
            found |= {p.stem for p in self.override.glob(f"*{SUFFIX}")}
        return sorted(found)

    def get(self, name: str) -> Prompt:
        """The prompt called `name`.

        Raises:
            UnknownIdError: no such prompt (with the closest name).
        """
        if name in self._cache:
            return self._cache[name]
        if not name or "/" in name or "\\" in name or name.startswith("."):
            raise InvalidInputError(f"prompt name {name!r} must be a plain file stem.")
        for folder in (self.override, package_prompts_dir()):
            if folder is None:
                continue
            path = folder / f"{name}{SUFFIX}"
            if path.is_file():
                prompt = _read(path, name)
                self._cache[name] = prompt
                return prompt
        names = self.names()
        raise UnknownIdError(
            f"no prompt named {name!r}.{did_you_mean(name, names)} Prompts: {names}."
        )

    def refs(self) -> dict[str, str]:
        """name -> `name@hash12` of every prompt loaded so far (for run headers)."""
        return {name: p.ref for name, p in sorted(self._cache.items())}


@lru_cache(maxsize=1)
def default_prompts() -> PromptSet:
    """The package's prompts, without overrides."""
    return PromptSet()
