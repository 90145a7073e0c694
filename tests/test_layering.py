"""The one-way flow of docs/architecture.md ("How it fits together"), checked on the imports.

Each rule is a package that must not import another; a violation names the file and the line.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "air_sitl"
IMPORT = re.compile(r"^\s*(?:from|import)\s+air_sitl\.(\w+)", re.MULTILINE)

# (package, packages it must not import): docs/architecture.md's table, the rules to keep.
RULES: list[tuple[str, set[str]]] = [
    ("state", {p.stem for p in PACKAGE.iterdir() if p.stem not in {"state", "__init__"}}),
    ("fdm", {"autopilot", "nav", "flightlog", "dataset", "recording", "mavlink", "bus", "camera"}),
    ("sensors", {"autopilot", "flightlog", "dataset", "recording", "mavlink", "bus", "camera"}),
    ("nav", {"flightlog", "dataset", "recording", "mavlink", "bus", "camera"}),
    ("mission", {"autopilot", "nav", "flightlog", "dataset", "mavlink", "bus", "fdm"}),
    ("autopilot", {"nav", "flightlog", "dataset", "recording", "mavlink", "bus", "fdm"}),
    ("camera", {"dataset", "bus", "mavlink", "recording"}),
    ("maps", {"camera", "dataset", "bus", "mavlink", "recording"}),
    ("flightlog", {"dataset", "bus", "mavlink", "recording"}),
    ("dataset", {"flightlog", "bus", "mavlink", "recording"}),
    ("mavlink", {"dataset", "bus", "flightlog", "recording", "video"}),
    ("video", {"dataset", "bus", "flightlog", "recording", "mavlink", "runner", "autopilot"}),
    ("bus", {"dataset", "mavlink", "flightlog", "recording"}),
    ("localize", {"runner", "autopilot", "recording"}),
    ("eval", {"localize", "runner", "recording"}),
    # The pytest plugin drives the real command line, as a user's test does.
    ("testing", {p.stem for p in PACKAGE.iterdir() if p.stem not in {"testing", "__init__"}}),
]


def _imports(package: str) -> list[tuple[Path, int, str]]:
    root = PACKAGE / package
    files = sorted(root.rglob("*.py")) if root.is_dir() else [PACKAGE / f"{package}.py"]
    found = []
    for path in files:
        text = path.read_text(encoding="utf-8")
        for m in IMPORT.finditer(text):
            found.append((path, text.count("\n", 0, m.start()) + 1, m.group(1)))
    return found


@pytest.mark.parametrize(("package", "forbidden"), RULES, ids=[r[0] for r in RULES])
def test_package_keeps_the_one_way_flow(package: str, forbidden: set[str]) -> None:
    bad = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: imports air_sitl.{name}"
        for path, line, name in _imports(package)
        if name in forbidden
    ]
    assert not bad, "\n".join(bad)


# Modules inside a package whose arrow points one way: the renderer owns its per-pixel paths
# (remap), which march rays (relief, relief_march); none of those reaches back up, even for
# type hints. The map and surface a flight flies over are opened by maps, not by the camera.
MODULE_IMPORT = re.compile(r"^\s*(?:from|import)\s+air_sitl\.([\w.]+)", re.MULTILINE)
MODULE_RULES: list[tuple[str, set[str]]] = [
    ("camera/remap.py", {"camera.render", "camera.options", "camera.bridge"}),
    ("camera/relief.py", {"camera.render", "camera.remap", "camera.options"}),
    ("camera/relief_march.py", {"camera.render", "camera.remap", "camera.relief"}),
]


@pytest.mark.parametrize(("module", "forbidden"), MODULE_RULES, ids=[r[0] for r in MODULE_RULES])
def test_module_keeps_the_one_way_flow(module: str, forbidden: set[str]) -> None:
    path = PACKAGE / module
    text = path.read_text(encoding="utf-8")
    bad = []
    for m in MODULE_IMPORT.finditer(text):
        name = m.group(1)
        if any(name == f or name.startswith(f + ".") for f in forbidden):
            bad.append(f"{module}:{text.count(chr(10), 0, m.start()) + 1}: imports air_sitl.{name}")
    assert not bad, "\n".join(bad)


def test_maps_and_surfaces_are_chosen_and_opened_in_maps() -> None:
    """A flight's set-up opens (and closes) its map and surface model through maps.choose,
    whose one home they are; the camera only renders what it is handed."""
    homes = {
        name: sorted(
            path.relative_to(PACKAGE).as_posix()
            for path in PACKAGE.rglob("*.py")
            if re.search(rf"^def {name}\(", path.read_text(encoding="utf-8"), re.MULTILINE)
        )
        for name in ("open_chosen_map", "open_chosen_surface", "close_map")
    }
    assert homes == {name: ["maps/choose.py"] for name in homes}, homes


# Missions are validated once, where they come in: a plan file, a MAVLink upload. What flies
# them (autopilot, runner) trusts the Mission it is handed.
VALIDATION_EDGES = {"mission/plan_file.py", "mavlink/mission_protocol.py"}


def test_missions_are_validated_only_at_the_edges() -> None:
    callers = {
        path.relative_to(PACKAGE).as_posix()
        for path in PACKAGE.rglob("*.py")
        if re.search(r"\bcheck_(?:mission|item)\b", path.read_text(encoding="utf-8"))
    }
    assert callers - {"mission/validate.py"} == VALIDATION_EDGES


# Import circles between modules (TYPE_CHECKING imports included: they are arrows too). The
# MAVLink vehicle's parts know the endpoint through ``mavlink.interfaces.EndpointLike``, never by
# importing ``mavlink.vehicle``. Circles already there, inside one package each, are left to
# their packages (a circle across packages, or in any other package, fails):
KNOWN_CIRCLE_PACKAGES = ("air_sitl.camera", "air_sitl.dataset", "air_sitl.localize", "air_sitl.nav")
FROM_IMPORT = re.compile(r"^\s*from\s+(air_sitl[\w.]*)\s+import\s+(\([^)]*\)|[^\n]*)", re.MULTILINE)
PLAIN_IMPORT = re.compile(r"^\s*import\s+(air_sitl[\w.]*)", re.MULTILINE)


def _module_graph() -> dict[str, set[str]]:
    """Module -> the air_sitl modules it imports (``from P import m`` counts as P.m when m is a
    module, else as P)."""
    modules: dict[str, Path] = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        modules[name] = path
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        text = path.read_text(encoding="utf-8")
        deps: set[str] = set()
        for m in FROM_IMPORT.finditer(text):
            for item in m.group(2).strip("()").replace("\n", ",").split(","):
                word = item.split("#")[0].strip().split(" as ")[0].strip()
                if not word:
                    continue
                sub = f"{m.group(1)}.{word}"
                deps.add(sub if sub in modules else m.group(1))
        deps.update(m.group(1) for m in PLAIN_IMPORT.finditer(text))
        graph[name] = {d for d in deps if d in modules and d != name}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected groups of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[frozenset[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = set()
            while True:
                w = stack.pop()
                group.add(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(frozenset(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_new_import_circle() -> None:
    def known(circle: frozenset[str]) -> bool:
        return any(
            all(m == p or m.startswith(f"{p}.") for m in circle) for p in KNOWN_CIRCLE_PACKAGES
        )

    new = [sorted(c) for c in _circles(_module_graph()) if not known(c)]
    assert not new, f"import circles: {new}"


def test_the_circle_check_sees_a_type_checking_import() -> None:
    graph = _module_graph()
    assert "air_sitl.mavlink.interfaces" in graph["air_sitl.mavlink.camera"]
    graph["air_sitl.mavlink.interfaces"] = graph["air_sitl.mavlink.interfaces"] | {
        "air_sitl.mavlink.vehicle"
    }
    assert any("air_sitl.mavlink.vehicle" in c for c in _circles(graph))
