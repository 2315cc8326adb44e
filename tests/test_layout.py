"""The rules of the house (README, "Architecture"), read from the code's own imports.

* imports point one way: ``addon → app → core``; inside ``core`` every stage imports only
  ``core.model``, ``core.geometry`` and itself (``core.geometry`` only ``core.model``);
* ``app`` and ``addon`` are rooms (:data:`APP_ROOMS`, :data:`ADDON_ROOMS`), each importing only
  itself and the rooms below it;
* no import cycle between modules, counting imports placed inside functions and the
  ``if TYPE_CHECKING:`` ones (a cycle of types is a cycle of meaning);
* no ``_private`` name is taken from another module, and a private module (``_kernels.py``) is
  imported only by the modules of its own folder;
* ``core`` and ``app`` import without Blender; the root package imports without ``bpy``;
* no module of ``core``/``app`` is over 600 lines or has a function over 80 lines.
"""
import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
ROOTS = ("core", "app", "addon")
#: what each room may import besides itself (rooms are the first two name parts inside core)
CORE_BASE = {"core.model": set(), "core.geometry": {"core.model"}}
#: the rooms of ``app`` and ``addon``, lowest first: a room imports only itself and rooms before it
#: (``app`` is its package face, ``addon`` its top: registration and ``blender -b``)
APP_ROOMS = ("app.pictures", "app.web", "app.flow", "app.warmup", "app.batch", "app.cli")
ADDON_ROOMS = ("addon.scene", "addon.operators", "addon.ui", "addon")
ADDON_TOP = {"addon", "addon.headless"}
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80


def _modules():
    out = {}
    for root in ROOTS:
        for f in sorted((REPO / root).rglob("*.py")):
            parts = list(f.relative_to(REPO).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            if is_pkg:
                parts = parts[:-1]
            out[".".join(parts)] = (f, is_pkg)
    return out


MODULES = _modules()


def _imports(name):
    """(target module, imported names, line) for every import of ``name``, at any depth."""
    path, is_pkg = MODULES[name]
    package = name if is_pkg else name.rpartition(".")[0]
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = package.split(".")[: len(package.split(".")) - node.level + 1]
            target = ".".join(base + ([node.module] if node.module else []))
            for alias in node.names:
                sub = f"{target}.{alias.name}" if target else alias.name
                if sub in MODULES:
                    yield sub, None, node.lineno
                else:
                    yield target, alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("anatomesh."):
            yield node.module[len("anatomesh."):], None, node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("anatomesh."):
                    yield alias.name[len("anatomesh."):], None, node.lineno


def _room(module):
    parts = module.split(".")
    if parts[0] == "core" and len(parts) > 1 and (
            len(parts) > 2 or MODULES.get(module, (None, False))[1]):
        return ".".join(parts[:2])
    return parts[0]


def _allowed(src_room, dst_room):
    if src_room == dst_room:
        return True
    if src_room == "addon":
        return dst_room.split(".")[0] in ("core", "app")
    if src_room == "app":
        return dst_room.split(".")[0] == "core"
    if src_room == "core":  # the package face: core/__init__.py and core-level modules
        return dst_room.startswith("core")
    if src_room in CORE_BASE:
        return dst_room in CORE_BASE[src_room]
    return dst_room in ("core.model", "core.geometry")


EDGES = [(src, dst, what, line) for src in MODULES for dst, what, line in _imports(src)]


def test_imports_point_one_way():
    bad = [f"{MODULES[s][0].relative_to(REPO)}:{line} imports {d} ({_room(s)} -> {_room(d)})"
           for s, d, _, line in EDGES if d in MODULES and not _allowed(_room(s), _room(d))]
    assert not bad, "imports against the direction addon -> app -> core (stages -> model/geometry):\n" + "\n".join(bad)


def _app_room(module):
    """The room of an ``app``/``addon`` module (its first two name parts), or None elsewhere."""
    parts = module.split(".")
    if parts[0] not in ("app", "addon"):
        return None
    if module in ("app", *ADDON_TOP):
        return parts[0]
    return ".".join(parts[:2])


def test_app_and_addon_are_rooms():
    rooms = set(APP_ROOMS) | set(ADDON_ROOMS) | {"app"}
    loose = [m for m in MODULES if _app_room(m) and _app_room(m) not in rooms]
    assert not loose, "modules of app/addon outside their rooms:\n" + "\n".join(sorted(loose))


def test_rooms_import_downward():
    order = {r: i for rooms in (APP_ROOMS, ADDON_ROOMS) for i, r in enumerate(rooms)}
    bad = [f"{MODULES[s][0].relative_to(REPO)}:{line} imports {d} ({_app_room(s)} -> {_app_room(d)})"
           for s, d, _, line in EDGES if d in MODULES and _app_room(s) in order and _app_room(d) in order
           and s.split(".")[0] == d.split(".")[0] and order[_app_room(d)] > order[_app_room(s)]]
    assert not bad, "imports up the rooms of app/addon:\n" + "\n".join(bad)


def test_no_import_cycles():
    graph = {m: set() for m in MODULES}
    for s, d, _, _ in EDGES:
        if d in MODULES and d != s:
            graph[s].add(d)
    cycles = _cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_no_private_names_across_modules():
    bad = []
    for s, d, what, line in EDGES:
        where = f"{MODULES[s][0].relative_to(REPO)}:{line}"
        if what is not None and what.startswith("_") and not what.startswith("__"):
            bad.append(f"{where} takes {what} from {d}")
        leaf = d.rpartition(".")[2]
        if d in MODULES and leaf.startswith("_") and not leaf.startswith("__") and \
                d.rpartition(".")[0] != (s if MODULES[s][1] else s.rpartition(".")[0]):
            bad.append(f"{where} imports the private module {d} of another folder")
    assert not bad, "\n".join(bad)


def test_no_module_or_function_too_long():
    bad = []
    for name, (path, _) in MODULES.items():
        if not name.startswith(("core", "app")):
            continue
        text = path.read_text()
        if text.count("\n") > MAX_MODULE_LINES:
            bad.append(f"{path.relative_to(REPO)}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    bad.append(f"{path.relative_to(REPO)}:{node.lineno} {node.name}: {n} lines")
    assert not bad, "\n".join(bad)


def test_core_and_app_import_without_blender():
    code = ("import sys, anatomesh, anatomesh.core, anatomesh.app.cli, anatomesh.app.flow.run; "
            "assert 'bpy' not in sys.modules, 'bpy imported'; "
            "assert 'anatomesh.addon' not in sys.modules; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan 1972), sorted."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
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
    return sorted(out)


@pytest.mark.parametrize("graph, expected", [
    ({"a": {"b"}, "b": {"a"}, "c": set()}, [["a", "b"]]),
    ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
])
def test_cycle_finder_itself(graph, expected):
    assert _cycles(graph) == expected
