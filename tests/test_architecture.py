"""The architecture of the package, checked from its source (docs/architecture.md).

* layers: a module imports only from its own layer or lower ones (module-level and
  function-level imports alike), with the exceptions listed in ``UPWARD`` and their reasons;
  the pairs in ``NEVER`` never import each other's way even within a layer; the parts of the
  package import each other in no circle (the listed exceptions aside);
* the map: docs/architecture.md names every module of the package;
* size: no module over ``MODULE_LINES`` lines, no function body over ``FUNCTION_LINES``
  lines unless its ``def`` line carries a ``# long: <reason>`` comment, no test file over
  ``TEST_FILE_LINES`` lines;
* privacy: no leading-underscore name of a shapeflow module is imported or used as an
  attribute of a module outside it (source and tests).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "shapeflow"

#: rank of each top-level part of the package; a module may import ranks <= its own
LAYERS = {
    "errors": 0, "params": 0, "budget": 0, "accel": 0, "types": 0,
    "mesh": 1,
    "geometry": 2,
    "operators": 3,
    "linalg": 4,
    "flow": 5, "sculpt": 5, "subdivision": 5,
    "io": 6, "rendering": 6, "examples": 6, "interop": 6,
    "commands": 7, "blender": 7, "studio": 7, "__init__": 7,
    "cli": 8, "batch": 8, "__main__": 8,
}
#: allowed imports against the layering: (importer, imported) -> reason
UPWARD = {
    ("mesh.core", "geometry.measures"): "Mesh.diagnostics() counts zero-area faces with the polygon vector area",
    ("mesh.convert", "geometry.measures"): "trimesh and open3d hold triangles: the conversions split faces into fans",
}
#: imports that never happen, although the layers would allow them: (importer, imported) -> reason
NEVER = {
    ("batch", "cli"): "batch runs the commands' functions on their options; the command line is another of "
                      "their users, not a library",
}
MODULE_LINES = 600
FUNCTION_LINES = 80
TEST_FILE_LINES = 800
ARCHITECTURE = ROOT / "docs" / "architecture.md"


def modules():
    for p in sorted(SRC.rglob("*.py")):
        rel = p.relative_to(SRC).with_suffix("")
        parts = rel.parts
        if parts[0] == "blender" and len(parts) > 1 and parts[1] == "addon":
            continue   # runs inside Blender, imports shapeflow as a user would
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts) or "__init__"
        yield name, p


def imported_modules(name: str, path: Path):
    """Every shapeflow module ``name`` imports (absolute names without the ``shapeflow.`` prefix)."""
    tree = ast.parse(path.read_text())
    pkg = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[:len(pkg) - node.level + 1] if node.level > 1 else pkg
                mod = ".".join([*base, *(node.module.split(".") if node.module else [])])
            elif node.module and node.module.startswith("shapeflow"):
                mod = node.module[len("shapeflow."):] if node.module != "shapeflow" else ""
            else:
                continue
            for alias in node.names:
                yield (f"{mod}.{alias.name}" if mod else alias.name), node.lineno, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("shapeflow."):
                    yield alias.name[len("shapeflow."):], node.lineno, alias.name


def layer(mod: str) -> int | None:
    return LAYERS.get(mod.split(".")[0])


def test_every_part_has_a_layer():
    tops = {name.split(".")[0] for name, _ in modules()}
    assert tops <= set(LAYERS), tops - set(LAYERS)


def test_lower_layers_never_import_higher_ones():
    bad = []
    for name, path in modules():
        mine = layer(name)
        for target, line, _ in imported_modules(name, path):
            theirs = layer(target)
            if theirs is None or theirs <= mine:
                continue
            if any(name == a and target.startswith(b) for a, b in UPWARD):
                continue
            bad.append(f"{path.relative_to(ROOT)}:{line} ({name}, layer {mine}) imports {target} (layer {theirs})")
    assert not bad, "\n".join(bad)


def test_the_listed_exceptions_exist():
    """Every allowed upward import is still made (else the exception is stale)."""
    made = {(name, target) for name, path in modules() for target, _, _ in imported_modules(name, path)}
    for a, b in UPWARD:
        assert any(n == a and t.startswith(b) for n, t in made), (a, b)


def test_the_never_pairs_hold():
    bad = [f"{path.relative_to(ROOT)}:{line} imports {target} ({NEVER[(a, b)]})"
           for name, path in modules() for target, line, _ in imported_modules(name, path)
           for a, b in NEVER if name.split(".")[0] == a and target.split(".")[0] == b]
    assert not bad, "\n".join(bad)


def part_graph() -> dict[str, dict[str, list[str]]]:
    """Which top-level part (subpackage or module) imports which, with the imports that tie them
    (``{importer: {imported: ["module -> target", ...]}}``); the listed upward exceptions left out."""
    graph: dict[str, dict[str, list[str]]] = {}
    for name, path in modules():
        for target, _, _ in imported_modules(name, path):
            a, b = name.split(".")[0], target.split(".")[0]
            if a == b or layer(target) is None or any(name == x and target.startswith(y) for x, y in UPWARD):
                continue
            graph.setdefault(a, {}).setdefault(b, []).append(f"{name} -> {target}")
    return graph


def circles(graph: dict[str, dict]) -> list[list[str]]:
    """The strongly connected parts of ``graph`` with more than one member (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while comp[-1:] != [v]:
                comp.append(stack.pop())
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_circles_are_found():
    assert circles({"a": {"b": []}, "b": {"c": []}, "c": {"a": []}, "d": {"a": []}}) == [["a", "b", "c"]]
    assert circles({"a": {"b": []}, "b": {}}) == []


def test_no_circle_among_the_parts():
    graph = part_graph()
    assert "batch" in graph and "cli" in graph["__main__"]        # the graph is read at all
    bad = [f"{' <-> '.join(c)}: " + "; ".join(t for a in c for b in c for t in graph.get(a, {}).get(b, [])[:2])
           for c in circles(graph)]
    assert not bad, "\n".join(bad)


def test_every_module_is_on_the_map():
    """docs/architecture.md names every module by its path in the package (a package's
    ``__init__.py`` may be named by its folder, ``accel/``)."""
    text = ARCHITECTURE.read_text()
    missing = []
    for p in sorted(SRC.rglob("*.py")):
        rel = p.relative_to(SRC).as_posix()
        folder = rel[:-len("__init__.py")] if p.name == "__init__.py" else ""
        if f"`{rel}`" not in text and not (folder and f"`{folder}`" in text):
            missing.append(rel)
    assert not missing, f"docs/architecture.md does not name: {', '.join(missing)}"


@pytest.mark.parametrize("name, path", list(modules()), ids=[n for n, _ in modules()])
def test_module_size(name, path):
    lines = len(path.read_text().splitlines())
    assert lines <= MODULE_LINES, f"{path.relative_to(ROOT)} has {lines} lines"


def test_no_test_file_is_too_long():
    sizes = {p.relative_to(ROOT).as_posix(): len(p.read_text().splitlines()) for p in (ROOT / "tests").rglob("*.py")}
    assert len(sizes) > 50                                  # the tests are read at all
    long = {name: n for name, n in sorted(sizes.items()) if n > TEST_FILE_LINES}
    assert not long, long


def _body_lines(fn) -> int:
    body = fn.body
    if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant) \
            and isinstance(body[0].value.value, str):
        body = body[1:]
    return body[-1].end_lineno - body[0].lineno + 1 if body else 0


def test_function_size():
    bad = []
    for name, path in modules():
        text = path.read_text()
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = _body_lines(node)
                head = lines[node.lineno - 1:node.body[0].lineno - 1]
                if n > FUNCTION_LINES and not any("# long:" in h for h in head):
                    bad.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {n} lines")
    assert not bad, "\n".join(bad)


def _private_uses(path: Path, aliases_of_modules: bool = True):
    """Leading-underscore names of shapeflow modules imported or read as module attributes."""
    tree = ast.parse(path.read_text())
    module_aliases = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("shapeflow")):
            if any(part.startswith("_") and not part.startswith("__") for part in (node.module or "").split(".")):
                yield node.lineno, node.module
            for alias in node.names:
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    yield node.lineno, alias.name
                else:
                    module_aliases.add(alias.asname or alias.name)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("shapeflow"):
                    module_aliases.add(alias.asname or alias.name.split(".")[0])
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            base = node.value
            while isinstance(base, ast.Attribute):
                base = base.value
            if isinstance(base, ast.Name) and base.id in module_aliases | {"sf", "shapeflow"} \
                    and base.id not in ("self", "cls"):
                yield node.lineno, ast.unparse(node)


def test_no_private_name_is_used_outside_its_module():
    bad = []
    files = [p for _, p in modules()] + sorted((ROOT / "tests").glob("**/*.py")) \
        + sorted((ROOT / "benchmarks").glob("*.py")) + sorted((ROOT / "docs").glob("*.py"))
    for p in files:
        for line, what in _private_uses(p):
            bad.append(f"{p.relative_to(ROOT)}:{line} {what}")
    assert not bad, "\n".join(bad)


def _public_callables():
    import inspect

    import shapeflow as sf

    for name in sf.__all__:
        obj = getattr(sf, name)
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            for m, f in vars(obj).items():
                if (not m.startswith("_") or m == "__init__") and inspect.isfunction(f):
                    yield f"{name}.{m}", f
                elif isinstance(f, property) and f.fget is not None and not m.startswith("_"):
                    yield f"{name}.{m}", f.fget


def test_the_public_api_is_typed():
    """Every parameter and return value of the public API has a type (the package ships py.typed)."""
    import inspect

    assert (SRC / "py.typed").is_file()
    bad = []
    for name, f in _public_callables():
        sig = inspect.signature(f)
        for p, v in sig.parameters.items():
            if p in ("self", "cls") or v.kind in (v.VAR_KEYWORD, v.VAR_POSITIONAL):
                continue
            if v.annotation is inspect.Parameter.empty:
                bad.append(f"{name}({p})")
        if sig.return_annotation is inspect.Signature.empty and not name.endswith("__init__"):
            bad.append(f"{name} -> ?")
    assert not bad, bad


#: the messages of the per-vertex weights check: raised in ``mesh/weights.py`` alone
WEIGHT_CHECK_TEXTS = ("must lie in [0, 1]; vertex", "weight of vertex", ", outside [0, 1] ")


def raised_texts(path: Path) -> str:
    """The string pieces of every ``raise`` statement of a module (f-strings' literal parts too)."""
    pieces = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Raise):
            pieces += [c.value for c in ast.walk(node) if isinstance(c, ast.Constant) and isinstance(c.value, str)]
    return "\n".join(pieces)


def test_the_weights_check_is_written_once():
    """Every entry point takes weights through ``shapeflow.mesh.weights`` (flow, brushes, studio, the
    ``weight`` attribute, weight files, the commands): no other module raises the check's messages."""
    home = SRC / "mesh" / "weights.py"
    assert all(t in raised_texts(home) for t in WEIGHT_CHECK_TEXTS)
    bad = [f"{p.relative_to(ROOT)}: {t!r}" for _, p in modules() if p != home
           for t in WEIGHT_CHECK_TEXTS if t in raised_texts(p)]
    assert not bad, "\n".join(bad)


#: modules that hold kernels: each family's NumPy/SciPy reference (``<package>/kernels.py``) and its
#: numba implementation (``<package>/compiled*.py``)
KERNEL_MODULE = re.compile(r"(^|/)(kernels|compiled\w*)\.py$")
#: modules that may still look at the compiled modules themselves: path -> reason
KERNEL_CHOICE_EXCEPTIONS = {
    "linalg/blas.py": "split_routines finds LAPACK's pointers for the compiled split solver through numba's "
                      "cython lookup (only the numba implementation of the local family calls it)",
    "commands/common.py": "note_compiling says a first run compiles: it looks for numba's cache files of the "
                          "compiled modules, and whether the current settings run compiled at that size",
}


def kernel_choices(name: str, path: Path):
    """Where a module chooses a kernel's implementation itself: ``accel.compiled(...)`` or
    ``.uses_compiled(...)``, an import of a compiled module or of numba, or a compiled module's name
    in a string (``importlib``)."""
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr in ("compiled", "uses_compiled"):
            yield node.lineno, ast.unparse(node.func)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            if any(m.split(".")[0] == "numba" for m in mods):
                yield node.lineno, "imports numba"
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and re.search(r"\.compiled\b", node.value) and "\n" not in node.value:
            yield node.lineno, f"names {node.value!r}"
    for target, line, _ in imported_modules(name, path):
        if any(part.startswith("compiled") for part in target.split(".")[1:]):
            yield line, f"imports {target}"


def test_kernels_are_chosen_through_accel_kernels_alone():
    """No module outside ``accel/`` and the kernel modules picks between a compiled kernel and its NumPy
    twin: they call ``accel.kernels(family, size)`` and its methods (the listed exceptions aside)."""
    from shapeflow import accel

    assert not hasattr(accel, "compiled")
    bad, seen = [], set()
    for name, path in modules():
        rel = path.relative_to(SRC).as_posix()
        if rel.startswith("accel/") or KERNEL_MODULE.search(rel):
            continue
        found = list(kernel_choices(name, path))
        if rel in KERNEL_CHOICE_EXCEPTIONS:
            seen.add(rel) if found else None
            continue
        bad += [f"{path.relative_to(ROOT)}:{line}: {what}" for line, what in found]
    assert not bad, "\n".join(bad)
    assert seen == set(KERNEL_CHOICE_EXCEPTIONS), "stale exceptions: " + ", ".join(set(KERNEL_CHOICE_EXCEPTIONS) - seen)


def test_the_kernel_rule_sees_the_old_branching(tmp_path):
    """The rule above finds each way call sites used to choose (so it cannot pass by not looking)."""
    p = tmp_path / "m.py"
    p.write_text("from .. import accel\nfrom .compiled import edge_data\nimport numba\n"
                 "fast = accel.compiled('mesh', 10)\nok = accel.current().uses_compiled(10)\n"
                 "mod = importlib.import_module('shapeflow.mesh.compiled')\n")
    found = [what for _, what in kernel_choices("mesh.m", p)]
    assert found == ["imports numba", "accel.compiled", "accel.current().uses_compiled",
                     "names 'shapeflow.mesh.compiled'", "imports mesh.compiled.edge_data"], found
