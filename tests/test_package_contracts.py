"""The repository's own rules, checked on its source (issue 19).

- Each stage package's ``__init__`` is its public interface: across
  packages, code imports only from it, never from another package's
  private ``_module``.
- Imports run one way, down the stage order (``PACKAGES``): capture,
  simulate, reconstruct, the synthetic lab, compare, the benchmarks, the
  command. A package never imports a later one, not even at call time.
- The code cites the project's own docs/, never a document outside the
  repository.
"""

import ast
import re

from conftest import REPO

PACKAGES = ["capture", "simulate", "reconstruct", "lab", "compare", "benchmarks", "pipelines"]


def _imported_module(path, node):
    """The absolute ``dragline.*`` module an ``ImportFrom`` node names."""
    if node.level == 0:
        return node.module or ""
    parts = ["dragline", *path.relative_to(REPO).with_suffix("").parts]
    base = parts[:-1][: len(parts) - node.level]
    return ".".join(base + ([node.module] if node.module else []))


def _sources():
    for package in PACKAGES:
        yield from sorted((REPO / package).rglob("*.py"))


def test_no_package_imports_another_packages_private_module():
    crossings = []
    for path in _sources():
        package = path.relative_to(REPO).parts[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                parts = _imported_module(path, node).split(".")
                if parts[0] == "dragline" and len(parts) > 2 and parts[1] != package \
                        and any(p.startswith("_") for p in parts[2:]):
                    crossings.append(f"{path.relative_to(REPO)}:{node.lineno} imports {'.'.join(parts)}")
    assert not crossings, "\n".join(crossings)


def _dragline_imports(path):
    """(line, package) of every dragline package a source file imports, at any depth of the code."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            names = [_imported_module(path, node)]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "dragline" and len(parts) > 1:
                yield node.lineno, parts[1]


def test_imports_run_down_the_stage_order():
    upward = []
    for path in _sources():
        package = path.relative_to(REPO).parts[0]
        for lineno, target in _dragline_imports(path):
            if target in PACKAGES and PACKAGES.index(target) > PACKAGES.index(package):
                upward.append(f"{path.relative_to(REPO)}:{lineno} ({package}) imports {target}")
    assert not upward, "\n".join(upward)


def test_the_order_checker_sees_an_upward_import(tmp_path):
    """The rule above can fail: a capture module importing simulate is found."""
    (tmp_path / "capture").mkdir()
    source = tmp_path / "capture" / "_x.py"
    source.write_text("def f():\n    from ..simulate import simulate\n")
    node = ast.parse(source.read_text()).body[0].body[0]
    parts = _imported_module(REPO / "capture" / "_x.py", node).split(".")
    assert parts[:2] == ["dragline", "simulate"]
    assert PACKAGES.index(parts[1]) > PACKAGES.index("capture")


def test_the_checker_sees_a_private_crossing(tmp_path):
    """The rule above can fail: the same resolution applied to a line that crosses."""
    node = ast.parse("from ..capture._cameras import Camera").body[0]
    parts = _imported_module(REPO / "simulate" / "_model.py", node).split(".")
    assert parts == ["dragline", "capture", "_cameras"]


def test_code_and_tests_cite_only_documents_in_the_repository():
    # The brief's folder beside a checkout, named in pieces so this file does not cite it itself.
    brief = "sha" + "red"
    outside = re.compile(rf"\bDESIGN\s+\d|\.\./{brief}\b|/{brief}/|\b{brief}/(?:DESIGN|seed|data)")
    found = []
    documents = [*sorted((REPO / "docs").glob("*.md")), REPO / "README.md", *sorted(REPO.glob("*/data/*.toml")),
                 *sorted((REPO / "samples").rglob("*.md"))]
    for path in [*_sources(), *sorted((REPO / "tests").glob("*.py")), *sorted((REPO / "tools").glob("*.py")), *documents]:
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if outside.search(line):
                found.append(f"{path.relative_to(REPO)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)


# Packages whose code knows kinds, never the dragline's names (issue 35).
MACHINE_FREE = ["capture", "simulate", "reconstruct", "lab", "pipelines", "compare", "benchmarks"]
# The dragline's own data inside them: its maneuver generator and the paper's report preset.
DRAGLINE_DATA = {"simulate/_dig.py", "compare/_paper.py"}


def _docstring_nodes(tree):
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                yield first.value


def _dragline_names():
    """Every name the built-in rig file gives: bodies, points, markers, ropes, winches, rings, columns."""
    from dragline.simulate import load_rig

    rig = load_rig()
    names = set(rig.bodies) | set(rig.ropes) | set(rig.fixed_points) | set(rig.winches)
    names |= {f"{w}_length" for w in rig.winches} | {site for r in rig.ropes.values() for site in r.ring_sites}
    for body in rig.bodies.values():
        names |= set(body.points)
    return names


def test_the_machine_free_packages_name_no_part_of_the_dragline():
    """Code in these packages holds no key (a string such as ``"bucket"`` or ``"hoist_rope.length"``,
    not prose, docstrings or comments) or identifier that names a body, point, rope, winch, ring or
    maneuver column of the built-in rig: they read them from the rig file. (An identifier ``drag``
    is air drag, the physics, not the drag winch: the winches are checked as keys only.)"""
    from dragline.simulate import load_rig

    forbidden = _dragline_names()
    identifiers = forbidden - set(load_rig().winches)
    found = []
    for package in MACHINE_FREE:
        for path in sorted((REPO / package).rglob("*.py")):
            rel = path.relative_to(REPO).as_posix()
            if rel in DRAGLINE_DATA:
                continue
            tree = ast.parse(path.read_text())
            docstrings = {id(n) for n in _docstring_nodes(tree)}
            for node in ast.walk(tree):
                if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
                    if not re.fullmatch(r"[A-Za-z0-9_.:]+", node.value):
                        continue  # prose: a message, not a key
                    tokens = set(re.split(r"[.:]", node.value)) & forbidden
                elif isinstance(node, ast.Name):
                    tokens = {node.id} & identifiers
                elif isinstance(node, ast.Attribute):
                    tokens = {node.attr} & identifiers
                elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                    tokens = {node.name} & identifiers
                elif isinstance(node, ast.arg):
                    tokens = {node.arg} & identifiers
                else:
                    continue
                for token in sorted(tokens):
                    found.append(f"{rel}:{node.lineno} names {token!r}")
    assert not found, "\n".join(found)
