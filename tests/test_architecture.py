"""The shape of the package, held: simbot's layers, declared bottom up (`LAYERS`), with every
import pointing down them; no import cycle between modules, nor between packages at any depth; the
systems importing no other system; the client programs importing only the bus, the description and
the shared leaves; no module of simbot/, clients/ or benchmarks/ over 500 lines; and
`simbot/sim/systems/` holding exactly the registered systems.

The import graph is read from the source (every `import` and `from ... import` of a simbot
module, at any depth, those under `if TYPE_CHECKING:` included: a cycle that typing hides is still
a cycle a reader follows). The client programs are in it as the package they install as,
`simbot.clients` (clients/).

`.venv/bin/python -m pytest tests/test_architecture.py` checks it; a failure lists each import
that breaks the table, as `importer -> imported`."""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from importlib.metadata import entry_points
from pathlib import Path

from conftest import REPO

from simbot.sim.loop.registry import GROUP, ROBOT_GROUP, SENSOR_GROUP, WORLD_GROUP

PACKAGE = REPO / "simbot"
CLIENTS = REPO / "clients"
MAX_LINES = 500

LAYERS: tuple[tuple[str, ...], ...] = (
    ("simbot.transform", "simbot.plugins", "simbot.arguments", "simbot.memory", "simbot.sim.bullet"),
    ("simbot.description", "simbot.bus"),
    ("simbot.variation", "simbot.mapping", "simbot.dataset_format", "simbot.scan_merge"),
    ("simbot.sim.physics", "simbot.sim.render"),
    ("simbot.sim.loop",),
    ("simbot.sim.kit",),
    ("simbot.sim.systems",),
    ("simbot.sim",),
    ("simbot.gym", "simbot.clients"),
    ("simbot.cli",),
)
"""simbot's layers, bottom up, each a few packages (or modules) side by side:

0. the leaves every layer shares: transforms, plug-in loading, argument types, PyBullet itself;
1. the description (SDF and URDF as typed data, and the parameters of its plugins and sensors) and
   the bus (Zenoh, CDR, the messages), which know nothing of each other (SPEC §7);
2. what is made of a description or of the bus alone: randomised worlds, ground-truth maps,
   datasets on disk, merged scans;
3. the physics and the render workers, neither of which imports the other;
4. the simulation loop: the systems' contract, the world, world control;
5. the kit the systems share;
6. the systems;
7. the server (what is left of simbot.sim: the server and what only it uses);
8. the Gymnasium environments and the client programs;
9. the command line.

A module belongs to the longest of these names that it is or lies under. It imports its own
package and the layers below its own; sideways, within its layer, only as `SIDEWAYS` says."""
SIDEWAYS: Mapping[tuple[str, str], str] = {
    (
        "simbot.mapping",
        "simbot.variation",
    ): "`simbot map --seed` maps the randomised world it asks for (mapping/command.py)",
}
"""Imports between two packages of one layer, each with why it is so."""
SYSTEMS = "simbot.sim.systems"
SYSTEM_BASES: Mapping[str, str] = {
    "simbot.sim.systems.camera": "a camera of another kind (depth, RGBD, segmentation, thermal, wide-angle, "
    "bounding-box) is the camera system specialised: it subclasses `Camera` and declares its products",
}
"""The only systems another system may import, each with why: every other piece that two systems
share lives in the kit (simbot/sim/kit/) or below."""


def _module(path: Path) -> str:
    """The dotted name `path` imports as: clients/ installs as simbot.clients."""
    parts = path.relative_to(REPO).with_suffix("").parts
    parts = ("simbot", *parts) if parts[0] == "clients" else parts
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
    """Module → the simbot modules it imports, for simbot/ and clients/ (as simbot.clients)."""
    files = {_module(path): path for folder in (PACKAGE, CLIENTS) for path in folder.rglob("*.py")}
    modules = set(files)
    return {name: _imports(path, modules) - {name} for name, path in files.items()}


def _cycles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """Strongly connected components of more than one node (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for other in sorted(graph.get(node, ())):
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


def _packages(graph: Mapping[str, Iterable[str]], depth: int) -> dict[str, set[str]]:
    """The graph between packages `depth` names deep (`simbot.sim` at 2, `simbot.sim.kit` at 3): a
    module stands for its package of that depth, or for itself where it is shallower."""

    def package(module: str) -> str:
        return ".".join(module.split(".")[:depth])

    found: dict[str, set[str]] = {}
    for module, imported in graph.items():
        found.setdefault(package(module), set()).update(package(m) for m in imported)
    return {name: imported - {name} for name, imported in found.items()}


def _under(module: str, packages: Iterable[str]) -> bool:
    return any(module == package or module.startswith(package + ".") for package in packages)


def _layer(module: str) -> tuple[int, str] | None:
    """(the layer, the package of `LAYERS`) `module` belongs to: the longest name it is or lies under."""
    placed = [
        (len(name), level, name) for level, names in enumerate(LAYERS) for name in names if _under(module, [name])
    ]
    return max(placed)[1:] if placed else None


def _wrong_imports(graph: Mapping[str, Iterable[str]]) -> list[str]:
    """Each import that does not point down the layers (`importer -> imported: why`)."""
    wrong = []
    for module in sorted(graph):
        here = _layer(module)
        for imported in sorted(graph[module]):
            there = _layer(imported)
            if here is None or there is None:
                continue  # `test_every_module_has_a_layer` names it
            if here[1] == there[1] == SYSTEMS and imported not in SYSTEM_BASES:
                wrong.append(f"{module} -> {imported}: a system imports another system (share it through the kit)")
            elif here[1] == there[1] or there[0] < here[0] or (here[1], there[1]) in SIDEWAYS:
                continue
            elif there[0] > here[0]:
                wrong.append(f"{module} -> {imported}: up from layer {here[0]} to layer {there[0]}")
            else:
                wrong.append(f"{module} -> {imported}: sideways within layer {here[0]}")
    return wrong


def test_every_module_has_a_layer() -> None:
    graph = _graph()
    assert len(graph) > 200, f"only {len(graph)} modules found under {PACKAGE} and {CLIENTS}"
    assert any(_under(name, ["simbot.clients"]) for name in graph), "the client programs are not in the graph"
    assert sorted(name for name in graph if _layer(name) is None and name != "simbot") == []


def test_every_import_points_down_the_layers() -> None:
    graph = _graph()
    assert any(graph.values()), "no imports found: the reader is broken"
    assert _wrong_imports(graph) == []


def test_no_import_cycle_between_modules_nor_packages() -> None:
    """Dependencies point one way between modules, and between packages at every depth: a cycle
    of packages (the kit and the loop, the simulator and the maps) is one a reader follows too."""
    graph = _graph()
    depths = range(2, max(len(name.split(".")) for name in graph) + 1)
    assert {depth: _cycles(_packages(graph, depth)) for depth in depths} == {depth: [] for depth in depths}


def test_the_checks_find_a_wrong_import_and_a_cycle() -> None:
    """Each check can fail: an import up the layers, one sideways, one system importing another,
    a two-module and a three-module cycle, and a cycle that only the packages show."""
    graph = {
        "simbot.sim.loop.world": {"simbot.sim.kit.drive"},
        "simbot.bus.node": {"simbot.description.model"},
        "simbot.mapping.occupancy": {"simbot.variation.vary"},
        "simbot.sim.systems.thermal": {"simbot.sim.systems.label", "simbot.sim.systems.camera"},
        "simbot.sim.kit.drive": {"simbot.sim.loop.system", "simbot.description.model"},
    }
    assert _wrong_imports(graph) == [
        "simbot.bus.node -> simbot.description.model: sideways within layer 1",
        "simbot.sim.loop.world -> simbot.sim.kit.drive: up from layer 4 to layer 5",
        "simbot.sim.systems.thermal -> simbot.sim.systems.label: a system imports another system (share it through the kit)",
    ]
    cycles = {"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"e"}, "e": {"c"}, "f": {"a"}}
    assert sorted(_cycles(cycles)) == [["a", "b"], ["c", "d", "e"]]
    packaged = {"simbot.sim.kit.x": {"simbot.mapping.y"}, "simbot.mapping.y": {"simbot.sim.systems.z"}}
    assert _cycles(packaged) == []
    assert _cycles(_packages(packaged, 2)) == [["simbot.mapping", "simbot.sim"]]
    assert _layer("simbot.sim.server") == (7, "simbot.sim") and _layer("simbot.sim.bullet") == (0, "simbot.sim.bullet")
    assert _layer("simbot.clients.merger") == (8, "simbot.clients") and _layer("simbot.simulator") is None


def test_no_module_of_simbot_clients_or_benchmarks_is_over_500_lines() -> None:
    paths = [path for folder in (PACKAGE, REPO / "clients", REPO / "benchmarks") for path in folder.rglob("*.py")]
    sizes = {str(path.relative_to(REPO)): len(path.read_text().splitlines()) for path in paths}
    assert len(sizes) > 150, f"only {len(sizes)} modules found"
    assert {name: lines for name, lines in sizes.items() if lines > MAX_LINES} == {}


CLIENT_MAY_IMPORT = (
    "simbot.bus",
    "simbot.description",
    "simbot.transform",
    "simbot.dataset_format",
    "simbot.arguments",
    "simbot.scan_merge",
)
"""The layers a client program stands on: the bus, the description, and the leaves every layer shares."""


def test_the_clients_import_only_the_bus_the_description_and_the_shared_leaves() -> None:
    """Stricter than their layer: a client program is a process of its own that talks to the server
    only over the bus (SPEC §5), so it imports nothing of the simulator, nor of the gym."""
    graph = _graph()
    clients = [name for name in graph if _under(name, ["simbot.clients"])]
    assert len(clients) > 15, f"only {len(clients)} client modules found"
    found = {
        name: others
        for name in sorted(clients)
        if (others := sorted(m for m in graph[name] if not _under(m, [*CLIENT_MAY_IMPORT, "simbot.clients"])))
    }
    assert found == {}


def _client_imports(source: str) -> list[int]:
    """Lines importing a client program (`simbot.clients…`, or the checkout's `clients…`)."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        else:
            continue
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


def test_the_systems_folder_holds_exactly_the_registered_systems() -> None:
    """Each module of simbot/sim/systems/ is named by an entry point of a system group, and each of
    simbot's own entry points names a module there: what systems share lives in the kit."""
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
