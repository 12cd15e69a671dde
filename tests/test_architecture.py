"""The package's import graph, read from the source with ``ast`` (nothing is imported).

Rules (issue 13): no import cycles among ``skin_sim_node`` modules, the contract
(``msgs_schema``) imports nothing from the implementation, and at most 8 flat modules sit at the
top of ``skin_sim_node/``. Issue 18: the session uses only the model's public API (the package
``skin_sim_node.model``, none of its modules), and the model core (``skin_sim_node/model/``) imports
no rclpy and nothing from the session, the server, the device side or the benchmarks. Issue 28: the runtime
(``skin_sim_node``, ``msgs_schema``) imports nothing from the lab (``skin_sim_lab``); the lab may import the runtime. Run as
a script to print the graph's figures (modules per folder, edges, cycles, upward ties).
"""

from __future__ import annotations

import ast
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("skin_sim_node", "msgs_schema", "skin_sim_lab")
RUNTIME = ("skin_sim_node", "msgs_schema")
LAB = "skin_sim_lab"
MAX_FLAT_MODULES = 8


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _resolve(mod: str, is_pkg: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = mod.split(".")
    base = base if is_pkg else base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imported_names(mod: str, path: Path) -> list[str]:
    """Every name the file's imports bring in (function-level ones too), absolute: ``from .a import b`` gives
    ``pkg.a.b`` and ``pkg.a``."""
    is_pkg = path.name == "__init__.py"
    names: list[str] = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(mod, is_pkg, node)
            names += [f"{base}.{a.name}" for a in node.names] + [base]
    return names


def import_graph() -> dict[str, set[str]]:
    """``{module: {imported project modules}}``, every import in the file (function-level ones too)."""
    mods = modules()
    graph: dict[str, set[str]] = defaultdict(set)

    def target(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    for mod, path in mods.items():
        graph[mod]
        for n in imported_names(mod, path):
            t = target(n)
            # a package's own __init__ re-exports are not edges of its submodules
            if t and t != mod and not mod.startswith(t + "."):
                graph[mod].add(t)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    sys.setrecursionlimit(10_000)

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def flat_modules() -> list[str]:
    return sorted(p.stem for p in (ROOT / "skin_sim_node").glob("*.py") if p.stem != "__init__")


def test_no_import_cycles():
    assert cycles(import_graph()) == []


def test_contract_imports_nothing_from_the_implementation():
    g = import_graph()
    bad = {m: sorted(t for t in ts if t.startswith("skin_sim_node")) for m, ts in g.items() if m.startswith("msgs_schema")}
    assert {m: ts for m, ts in bad.items() if ts} == {}


def test_flat_modules_at_most_eight():
    assert len(flat_modules()) <= MAX_FLAT_MODULES, flat_modules()


def _within(mod: str, package: str) -> bool:
    return mod == package or mod.startswith(package + ".")


def test_runtime_imports_nothing_from_the_lab():
    """Issue 28: the runtime (``skin_sim_node``, ``msgs_schema``) imports nothing from ``skin_sim_lab``, not even inside a
    function; the lab may import the runtime (the CLI names the lab's commands as strings, imported when run)."""
    g = import_graph()
    runtime = [m for m in g if any(_within(m, pkg) for pkg in RUNTIME)]
    bad = {m: sorted(t for t in g[m] if _within(t, LAB)) for m in runtime}
    assert {m: ts for m, ts in bad.items() if ts} == {}
    names = {m: [n for n in imported_names(m, p) if _within(n, LAB)] for m, p in modules().items() if m in runtime}
    assert {m: ns for m, ns in names.items() if ns} == {}  # a lab name the graph would not resolve to a module counts too
    lab = [m for m in g if _within(m, LAB)]
    assert len(lab) > 50 and len(runtime) > 50
    assert any(_within(t, "skin_sim_node") for m in lab for t in g[m])  # the rule sees the lab's real imports of the runtime


def test_session_uses_only_the_model_package():
    """The session imports ``skin_sim_node.model`` (its public API) and none of the model's modules."""
    g = import_graph()
    session = [m for m in g if _within(m, "skin_sim_node.session")]
    bad = {m: sorted(t for t in g[m] if t.startswith("skin_sim_node.model.")) for m in session}
    assert {m: ts for m, ts in bad.items() if ts} == {}
    assert any("skin_sim_node.model" in g[m] for m in session)  # the rule sees the session's real import


MODEL_MAY_NOT_IMPORT = (
    "skin_sim_node.session",
    "skin_sim_node.server",
    "skin_sim_node.device",
    "skin_sim_node.tools",
    "skin_sim_lab",
)


def test_model_core_imports_no_rclpy_and_nothing_above_it():
    """``skin_sim_node/model/`` is the pure core: no rclpy, and none of the layers that use it."""
    g = import_graph()
    model = {m: p for m, p in modules().items() if _within(m, "skin_sim_node.model")}
    assert len(model) > 5
    ros = {m: sorted({n for n in imported_names(m, p) if _within(n, "rclpy")}) for m, p in model.items()}
    assert {m: ns for m, ns in ros.items() if ns} == {}
    up = {m: sorted(t for t in g[m] if any(_within(t, pkg) for pkg in MODEL_MAY_NOT_IMPORT)) for m in model}
    assert {m: ts for m, ts in up.items() if ts} == {}


def test_session_knows_no_tool():
    """Issue 28: the session composes the input policy, a tool and the limits with no tool-specific branch: it imports
    the tools' package (its seam), none of their modules, names no tool and asks no tool for an optional attribute."""
    g = import_graph()
    session = {m: p for m, p in modules().items() if _within(m, "skin_sim_node.session")}
    bad = {m: sorted(t for t in g[m] if t.startswith("skin_sim_node.tools.")) for m in session}
    assert {m: ts for m, ts in bad.items() if ts} == {}
    assert "skin_sim_node.tools" in g["skin_sim_node.session.haptic"]
    for m, p in session.items():
        text = p.read_text().lower()
        assert "needle" not in text and "getattr(self.model" not in text and "tool_shape" not in text, m


def test_tools_each_in_one_module():
    """Issue 28: each tool of ``tools.TOOLS`` is a class of its own module under ``skin_sim_node/tools/``, and the tissue
    model has no tool registry."""
    from skin_sim_node import tools

    homes = {shape: cls.__module__ for shape, cls in tools.TOOLS.items()}
    assert all(m.startswith("skin_sim_node.tools.") for m in homes.values()), homes
    assert len(set(homes.values())) == len(homes), homes
    text = (ROOT / "skin_sim_node/model/skin_model.py").read_text()
    assert "TOOL_MODELS" not in text and "__new__" not in text and "axis=None" not in text


def test_graph_reader_sees_real_edges():
    """The reader finds imports the code is known to make (else the rules above would pass vacuously)."""
    g = import_graph()
    assert "skin_sim_node.session" in g["skin_sim_node.server.node"]
    assert "msgs_schema.convert" in g["skin_sim_node.bags.offline"]
    assert "skin_sim_node.model.layout" in g["skin_sim_node.model.paper"]
    assert any(_within(n, "rclpy") for n in imported_names("skin_sim_node.server.node", ROOT / "skin_sim_node/server/node.py"))
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def report() -> str:
    g = import_graph()
    per_folder: dict[str, int] = defaultdict(int)
    for p in modules().values():
        per_folder[str(p.parent.relative_to(ROOT))] += 1
    # package-level ties that run both ways (folder A imports folder B and B imports A)
    pkg = {m: m.rpartition(".")[0] if modules()[m].name != "__init__.py" else m for m in g}
    pkg_edges = {(pkg[m], pkg[t]) for m, ts in g.items() for t in ts if pkg[m] != pkg[t]}
    two_way = sorted((a, b) for a, b in pkg_edges if (b, a) in pkg_edges and a < b)
    lines = [
        f"modules {len(g)}, edges {sum(len(v) for v in g.values())}, flat modules at the top {len(flat_modules())}",
        "modules per folder: " + ", ".join(f"{k} {v}" for k, v in sorted(per_folder.items())),
        f"cycles: {cycles(g) or 'none'}",
        f"package edges {len(pkg_edges)}; ties both ways between packages: {two_way or 'none'}",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(report())


def test_typed_parameter_views_match_the_specs():
    """Issue 28: mypy sees NodeParams and SessionParams through typed views; each has exactly the specs' fields, with
    their types, so the checker cannot drift from the classes the specs make at run time."""
    import dataclasses
    import typing

    from msgs_schema import parameters as p

    for view, made, specs in (
        (p.NodeParamsFields, p.NodeParams, p.NODE_PARAMETERS),
        (p.SessionParamsFields, p.SessionParams, p.SESSION_PARAMETERS),
    ):
        hints = typing.get_type_hints(view)
        assert hints == {s.name: s.type for s in specs}
        assert [f.name for f in dataclasses.fields(made)] == list(hints)
