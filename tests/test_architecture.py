"""The shape of the package, held: no import cycles inside simbot/, the layers (the render workers'
and the physics' code never import the simulation loop or its systems; the client programs import
only the bus, the description and the shared leaves), no module of simbot/, clients/ or
benchmarks/ over 500 lines, and `simbot/sim/systems/` holding exactly the registered systems.

The import graph is read from the source (every `import` and `from ... import` of a simbot
module, at any depth, those under `if TYPE_CHECKING:` included: a cycle that typing hides is still
a cycle a reader follows)."""

from __future__ import annotations

import ast
from importlib.metadata import entry_points
from pathlib import Path

from conftest import REPO

from simbot.sim.loop.registry import GROUP, ROBOT_GROUP, SENSOR_GROUP, WORLD_GROUP

PACKAGE = REPO / "simbot"
MAX_LINES = 500


def _module(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """The simbot modules `path` imports (a `from package import name` of a submodule counts as that submodule)."""
    found = set()
    package = _module(path) if path.name == "__init__.py" else _module(path).rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name in modules}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(
                    package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else [])
                )
            for alias in node.names:
                full = f"{base}.{alias.name}"
                found.add(full if full in modules else base)
    return found & modules


def _graph() -> dict[str, set[str]]:
    files = {_module(path): path for path in PACKAGE.rglob("*.py")}
    modules = set(files)
    return {name: _imports(path, modules) - {name} for name, path in files.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for other in sorted(graph[node]):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_no_import_cycle_inside_simbot() -> None:
    """Dependencies point one way: description → bus/sim core → systems → server."""
    graph = _graph()
    assert len(graph) > 50, f"only {len(graph)} modules found under {PACKAGE}"
    assert any(graph.values()), "no imports found: the reader is broken"
    assert _cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle() -> None:
    """The check above can fail: a two-module and a three-module cycle are found, a chain is not."""
    graph = {"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"e"}, "e": {"c"}, "f": {"a"}}
    assert sorted(_cycles(graph)) == [["a", "b"], ["c", "d", "e"]]


def test_no_module_of_simbot_clients_or_benchmarks_is_over_500_lines() -> None:
    paths = [path for folder in (PACKAGE, REPO / "clients", REPO / "benchmarks") for path in folder.rglob("*.py")]
    sizes = {str(path.relative_to(REPO)): len(path.read_text().splitlines()) for path in paths}
    assert len(sizes) > 150, f"only {len(sizes)} modules found"
    assert {name: lines for name, lines in sizes.items() if lines > MAX_LINES} == {}


LOOP = ("simbot.sim.loop", "simbot.sim.systems", "simbot.sim.server")
"""The simulation loop, its systems and the server: what the render workers and the physics never import."""
CLIENT_MAY_IMPORT = (
    "simbot.bus",
    "simbot.description",
    "simbot.transform",
    "simbot.dataset_format",
    "simbot.arguments",
    "simbot.scan_merge",
)
"""The layers a client program stands on: the bus, the description, and the leaves every layer shares."""


def _under(module: str, packages: tuple[str, ...]) -> bool:
    return any(module == package or module.startswith(package + ".") for package in packages)


def test_the_render_workers_and_the_physics_never_import_the_loop() -> None:
    graph = _graph()
    lower = {name for name in graph if _under(name, ("simbot.sim.render", "simbot.sim.physics"))}
    assert len(lower) > 30, f"only {len(lower)} render and physics modules found"
    found = {name: sorted(m for m in graph[name] if _under(m, LOOP)) for name in sorted(lower)}
    assert {name: imported for name, imported in found.items() if imported} == {}


def test_the_clients_import_only_the_bus_the_description_and_the_shared_leaves() -> None:
    simbot_modules = set(_graph())
    found = {}
    for path in sorted((REPO / "clients").glob("*.py")):
        imported = {m for m in _imports(path, simbot_modules | {"simbot"}) if m.startswith("simbot")}
        if others := sorted(m for m in imported if not _under(m, CLIENT_MAY_IMPORT)):
            found[path.name] = others
    assert found == {}


def _client_imports(source: str) -> list[int]:
    """Lines importing a client program (`simbot.clients…`, or the checkout's `clients…`)."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
        if isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        if any(_under(name, ("simbot.clients", "clients")) for name in names):
            lines.append(node.lineno)
    return lines


def test_the_library_never_imports_a_client_program() -> None:
    """simbot.clients installs from clients/, beside simbot/ in a checkout: a library module that
    imports it fails wherever the checkout's simbot/ is found first (issue 46)."""
    found = {
        str(path.relative_to(REPO)): lines
        for path in sorted(PACKAGE.rglob("*.py"))
        if (lines := _client_imports(path.read_text()))
    }
    assert found == {}
    assert _client_imports(
        "import simbot.clients.merger\nfrom clients.common import x\nfrom simbot.bus import y\n"
    ) == [1, 2]


def test_the_layer_checks_find_a_wrong_import() -> None:
    assert _under("simbot.sim.loop.world", LOOP) and _under("simbot.sim.server", LOOP)
    assert not _under("simbot.sim.loopy", LOOP)
    assert not _under("simbot.sim.kit.rates", CLIENT_MAY_IMPORT)


def test_the_systems_folder_holds_exactly_the_registered_systems() -> None:
    """Each module of simbot/sim/systems/ is named by an entry point of a system group, and each of
    simbot's own entry points names a module there: helpers live beside what uses them."""
    groups = (GROUP, SENSOR_GROUP, WORLD_GROUP, ROBOT_GROUP)
    registered = {
        point.value.split(":")[0]
        for group in groups
        for point in entry_points(group=group)
        if point.value.startswith("simbot.")
    }
    folder = {_module(path) for path in (PACKAGE / "sim" / "systems").glob("*.py") if path.name != "__init__.py"}
    assert folder == registered


BLAS_CALLS = {"dot", "vdot", "inner", "matmul", "tensordot", "multi_dot", "inv", "pinv", "solve", "lstsq", "det"}
"""numpy calls that hand their sums to BLAS or LAPACK, whose kernel (and last bit) the CPU picks."""
PRODUCTS = PACKAGE / "transform.py"
"""The one module that says how a product is summed (docs/reproducibility.md)."""


def _blas_calls(source: str) -> list[int]:
    """Lines calling a BLAS-backed numpy function, `x.dot(y)` and `np.linalg.norm(v)` of a whole
    array (its dot product; with `axis=` numpy squares and sums elementwise) included."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            name = node.func.attr
            whole_norm = name == "norm" and ast.unparse(node.func.value).endswith("linalg")
            if name in BLAS_CALLS or (whole_norm and not any(k.arg == "axis" for k in node.keywords)):
                lines.append(node.lineno)
    return lines


def test_no_published_value_is_summed_by_a_blas_kernel() -> None:
    """simbot/ and clients/ take their products from simbot.transform, never from BLAS: the
    behaviour test's runs under other kernels catch an `@` on its paths, this catches the calls anywhere."""
    found = {
        str(path.relative_to(REPO)): lines
        for folder in (PACKAGE, REPO / "clients")
        for path in sorted(folder.rglob("*.py"))
        if path != PRODUCTS and (lines := _blas_calls(path.read_text()))
    }
    assert not found, f"BLAS-backed numpy calls (use simbot.transform's products): {found}"


def test_the_blas_finder_finds_each_form() -> None:
    source = "a.dot(b)\nnp.linalg.inv(m)\nnp.linalg.norm(v)\nnp.linalg.norm(v, axis=1)\nmath.hypot(1, 2)\n"
    assert _blas_calls(source) == [1, 2, 3]
