"""The application (glmap_tools.app) and its two faces (server: MCP, toolset: in process)
import each other in one direction only, read from the sources with `ast` (every import,
those inside functions and under `if TYPE_CHECKING:` included)."""

from __future__ import annotations

import ast
import dataclasses
import typing
from pathlib import Path
from typing import Any

import glmap_tools

ROOT = Path(glmap_tools.__file__).parent
PACKAGES = ("app", "server", "toolset")


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def sources() -> dict[str, Path]:
    """{module name: file} of the three packages."""
    return {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def imported(path: Path, known: set[str]) -> set[str]:
    """The modules (of all glmap_tools, or `known` submodules) that `path` imports."""
    out: set[str] = set()
    package = module_name(path) if path.name == "__init__.py" else module_name(path.parent)
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                out.add(sub if sub in known else base)
    return out


def graph() -> dict[str, set[str]]:
    files = sources()
    known = set(files)
    return {name: imported(path, known) & known for name, path in files.items()}


def cycle_in(edges: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules (first = last), or None."""
    state: dict[str, int] = {}  # 1 = on the path, 2 = done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt) :] + [nxt]
            if nxt not in state and (found := visit(nxt)) is not None:
                return found
        path.pop()
        state[node] = 2
        return None

    for start in sorted(edges):
        if start not in state and (found := visit(start)) is not None:
            return found
    return None


def test_no_module_of_the_app_or_its_faces_is_in_an_import_cycle():
    cycle = cycle_in(graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_a_cycle_is_found_when_there_is_one():
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycle_in(edges) == ["a", "b", "c", "a"]
    assert cycle_in({"a": {"b"}, "b": set()}) is None


def test_the_mcp_server_and_the_toolset_do_not_import_each_other():
    edges = graph()
    for name, targets in edges.items():
        for face, other in (("server", "toolset"), ("toolset", "server")):
            if name.startswith(f"glmap_tools.{face}"):
                crossing = sorted(t for t in targets if t.startswith(f"glmap_tools.{other}"))
                assert not crossing, f"{name} imports {crossing}"


def test_the_app_imports_neither_face_nor_the_mcp_sdk():
    files = sources()
    for name, path in files.items():
        if not name.startswith("glmap_tools.app"):
            continue
        wrong = sorted(
            m
            for m in imported(path, set(files))
            if m.startswith(("glmap_tools.server", "glmap_tools.toolset", "mcp"))
        )
        assert not wrong, f"{name} imports {wrong}"


def test_a_session_and_the_app_state_are_typed_field_by_field():
    from glmap_tools.app import nav_session, runtime, session, state  # noqa: F401

    namespace = {**vars(session), **vars(nav_session), **vars(runtime)}
    namespace.update(_type_names())
    for cls in (session.Session, session.LiveMap, nav_session.NavSession, runtime.AppState):
        hints = typing.get_type_hints(cls, localns=namespace)
        for f in dataclasses.fields(cls):
            assert Any not in _leaves(hints[f.name]), f"{cls.__name__}.{f.name} is Any"


def _type_names() -> dict[str, Any]:
    """The names the dataclasses' string annotations use (imported for type checking)."""
    from glmap_tools.app.background import Background
    from glmap_tools.app.persist import PinnedMap
    from glmap_tools.app.simulator import SimEpisode
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.language.embed import Embedder
    from glmap_tools.map import GLMap
    from glmap_tools.nav import NavConfig, NavDecision, NavState, Scorer
    from glmap_tools.nav.perceive import TextVectors
    from glmap_tools.nav.scorers import ClientScores
    from glmap_tools.perception.pending import PendingFrames
    from glmap_tools.perception.semantics import FrameSemantics

    return {
        "Background": Background,
        "PinnedMap": PinnedMap,
        "SimEpisode": SimEpisode,
        "Embedder": Embedder,
        "GLMap": GLMap,
        "NavConfig": NavConfig,
        "NavDecision": NavDecision,
        "NavState": NavState,
        "Scorer": Scorer,
        "ClientScores": ClientScores,
        "TextVectors": TextVectors,
        "PendingFrames": PendingFrames,
        "RGBDFrame": RGBDFrame,
        "FrameSemantics": FrameSemantics,
    }


def _leaves(hint: Any) -> list[Any]:
    args = typing.get_args(hint)
    return [hint] if not args else [leaf for a in args for leaf in _leaves(a)]
