"""The package's layers (glmap_tools/design.md) import downwards only, and no modules import
each other in a circle: every import is read from the sources with `ast`, those inside
functions and under `if TYPE_CHECKING:` included.

An arrow that still runs upwards is listed in UPWARD with its reason, so a new one fails;
a listed arrow that is gone must leave the list too."""

from __future__ import annotations

import ast
from pathlib import Path

import glmap_tools

REPO = Path(glmap_tools.__file__).parent.parent
PACKAGES = ("glmap_tools", "agents")

# Lowest first. A module may import its own package's modules and those of lower layers.
# Packages on one line share a layer and do not import each other.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors",),
    # glmap_tools: the root's __version__; orphans, ray_cluster: the worker processes and the
    # Ray connection that batch builds (ingest) and evaluations (eval) share; launch_env: what
    # every launcher sets first; limits: bounds the settings check without numpy; checks: the
    # type predicates input checks share
    (
        "glmap_tools",
        "lazy",
        "atomic",
        "cli_format",
        "orphans",
        "ray_cluster",
        "launch_env",
        "limits",
        "checks",
    ),
    ("geometry",),
    ("gaussians",),
    ("language",),
    ("perception",),
    ("synthetic",),
    ("map",),
    ("nav",),
    ("views",),
    ("ingest",),  # RGB-D folders on disk; a simulator tour is written as one
    ("sim",),
    ("worlds",),  # generated scenes and the data sets drawn from them; a split builds its env
    ("sqa",),
    ("app",),
    ("server", "toolset"),
    ("agents",),
    ("eval",),
    ("cli",),  # `glmap`: loads its subcommands (ingest, worlds: sim, demo, language, eval) by name
    ("bench",),  # benchmarks may run `glmap` itself
    ("regression",),  # the replay check prints through bench's Report
)

# (importer, imported): why the arrow still runs upwards.
UPWARD: dict[tuple[str, str], str] = {
    ("glmap_tools.language.backends", "glmap_tools.nav"): (
        "make_scorer builds nav's f_S scorers from the LLM settings; it belongs beside them"
    ),
    ("glmap_tools.sim.env", "glmap_tools.worlds.generator"): (
        "an env made without a layout (`gymnasium.make`, `scene_seed`) generates its "
        "apartment; the generator needs the navigable grid below the env, so it cannot sit "
        "under sim"
    ),
    ("glmap_tools.sqa.diagnose", "glmap_tools.eval.sqa"): (
        "the SQA diagnosis reuses the evaluation's scene answering (its maps, its embedder): a "
        "report that belongs in eval, kept in sqa because `python -m glmap_tools.sqa.diagnose` "
        "is the command docs/evaluation.md gives"
    ),
    ("glmap_tools.server.demo", "agents.runner"): (
        "`glmap demo` plays a scripted agent against the server: a command of the agents' "
        "layer that lives with the server"
    ),
}

# Circles of modules that import each other, each with its reason (none now): a new one is
# broken by moving the shared names to where they belong.
CIRCLES: dict[frozenset[str], str] = {}


def module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def sources() -> dict[str, Path]:
    """{module name: file} of the package and the agents."""
    return {module_name(p): p for pkg in PACKAGES for p in sorted((REPO / pkg).rglob("*.py"))}


def imports(path: Path, known: set[str]) -> set[str]:
    """The known modules `path` imports (a name imported from a package that is one of its
    modules counts as that module)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            subs = [f"{base}.{alias.name}" for alias in node.names]
            targets = [sub if sub in known else base for sub in subs]
        else:
            continue
        for target in targets:
            while target not in known and "." in target:
                target = target.rpartition(".")[0]
            if target in known and target != name:
                out.add(target)
    return out


def graph() -> dict[str, set[str]]:
    files = sources()
    known = set(files)
    return {name: imports(path, known) for name, path in files.items()}


def layer_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if parts[0] == "glmap_tools" and len(parts) > 1 else parts[0]


def rank(module: str) -> int:
    layer = layer_of(module)
    for k, names in enumerate(LAYERS):
        if layer in names:
            return k
    raise AssertionError(f"{module} is in no layer: add {layer!r} to LAYERS")


def upward(edges: dict[str, set[str]]) -> set[tuple[str, str]]:
    """(importer, imported) pairs that import a higher layer or a peer of the same layer."""
    return {
        (a, b)
        for a, targets in edges.items()
        for b in targets
        if layer_of(a) != layer_of(b) and rank(b) >= rank(a)
    }


def circles(edges: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected groups of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[frozenset[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(frozenset(group))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_every_module_is_in_a_layer():
    for name in sources():
        rank(name)


def test_imports_flow_down_the_layers_except_the_listed_arrows():
    found = upward(graph())
    new = sorted(found - set(UPWARD))
    assert not new, "upward imports (move the shared code down, or list with a reason):\n" + (
        "\n".join(f"  {a} -> {b}" for a, b in new)
    )
    gone = sorted(set(UPWARD) - found)
    assert not gone, f"listed arrows that are gone (remove them from UPWARD): {gone}"


def test_no_modules_import_each_other_in_a_circle_except_the_listed_ones():
    found = circles(graph())
    new = [sorted(c) for c in found if c not in CIRCLES]
    assert not new, f"import circles (move the shared types to where they belong): {new}"
    gone = [sorted(c) for c in CIRCLES if c not in found]
    assert not gone, f"listed circles that are gone (remove them from CIRCLES): {gone}"


def test_an_upward_import_and_a_circle_are_found_when_there_are_some():
    edges = {
        "glmap_tools.map.a": {"glmap_tools.nav.b"},
        "glmap_tools.nav.b": {"glmap_tools.nav.c"},
        "glmap_tools.nav.c": {"glmap_tools.nav.b"},
        "glmap_tools.views.d": {"glmap_tools.map.a"},
    }
    assert upward(edges) == {("glmap_tools.map.a", "glmap_tools.nav.b")}
    assert circles(edges) == [frozenset({"glmap_tools.nav.b", "glmap_tools.nav.c"})]
