"""No module takes another module's private (underscore) names: what crosses a file is that
file's interface, named without an underscore and documented as such.

Every module of ``rig``, ``daq``, ``processing`` and ``benchmarks`` is read from its source
(ast, function-local imports included). A crossing is any of

- ``from X import _name`` (absolute or relative), ``X`` a project module other than the
  importer (a package's ``__init__.py`` re-exporting a submodule's private name is one too);
- an import of a private module: ``import X._mod``, ``from X._mod import y``,
  ``from X import _mod``;
- ``alias._name`` where ``alias`` is bound, in the same file, to a project module by an import
  (``import rig.bench as rb; rb._spawn``).

Dunder names (``__version__``) are not private. An alias does not count, only the imported
name (``from rig.validation import number as _number`` is fine). Not seen: ``getattr`` with a
string, and code inside strings (a benchmark's child process). The tests themselves are out of
scope: a test may reach into the module it tests.

The crossings still to remove are listed in :data:`ALLOWED`, each with its reason; an entry
that no longer occurs fails too, so the list only shrinks (it is empty: keep it so).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("rig", "daq", "processing", "benchmarks")

#: (importer, module, name) -> why it is still there; the list only shrinks
ALLOWED: dict = {}


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def project_modules(root: Path) -> dict[str, Path]:
    """Dotted module name -> source file, for every module of the project's packages."""
    mods = {}
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = path
    return mods


def _absolute(name: str, path: Path, node: ast.ImportFrom) -> str:
    """The module ``node`` imports from, relative imports resolved against ``name``."""
    if not node.level:
        return node.module or ""
    here = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    here = here[:len(here) - (node.level - 1)]
    return ".".join(here + ([node.module] if node.module else []))


def crossings_of(name: str, path: Path, known) -> set[tuple[str, str, str]]:
    """(importer, module, private name) of every crossing in module ``name`` (at ``path``);
    the name is empty for an import of a private module."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out, aliases = set(), {}

    def private_module(mod: str) -> None:
        if any(_private(p) for p in mod.split(".")):
            out.add((name, mod, ""))

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] not in PACKAGES:
                    continue
                private_module(a.name)
                if a.name in known:
                    aliases[a.asname or a.name.split(".")[0]] = (
                        a.name if a.asname else a.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            mod = _absolute(name, path, node)
            if mod.split(".")[0] not in PACKAGES:
                continue
            private_module(mod)
            for a in node.names:
                if _private(a.name) and mod != name:
                    out.add((name, mod, a.name))
                if f"{mod}.{a.name}" in known:
                    aliases[a.asname or a.name] = f"{mod}.{a.name}"
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and _private(node.attr)
                and aliases[node.value.id] != name):
            out.add((name, aliases[node.value.id], node.attr))
    return out


def crossings(root: Path) -> set[tuple[str, str, str]]:
    mods = project_modules(root)
    return set().union(*(crossings_of(m, p, mods) for m, p in mods.items()))


def test_no_module_imports_another_modules_private_names():
    found = sorted(c for c in crossings(ROOT) if c not in ALLOWED)
    assert not found, "private names across modules (make them public with a docstring "\
        "stating the contract, or move the code to its user):\n" + "\n".join(
            f"{m} takes {mod}.{n}" if n else f"{m} imports the private module {mod}"
            for m, mod, n in found)


def test_every_allowed_crossing_still_occurs():
    stale = sorted(set(ALLOWED) - crossings(ROOT))
    assert not stale, f"remove from ALLOWED (no longer crossing): {stale}"


def test_the_walk_sees_the_project():
    mods = project_modules(ROOT)
    assert {"rig.bench.run", "daq.hdf5", "processing.modal", "benchmarks.acquire"} <= set(mods)


def test_the_check_catches_planted_crossings(tmp_path):
    """A tree with each kind of crossing (a plain and a function-local import of a private
    name, a relative one, a package re-exporting one, a private module imported three ways, an
    attribute through a module alias) is found; a private alias of a public name, a dunder, a
    module's own private names, its own attributes and a non-project import are not."""
    files = {
        "rig/__init__.py": "from rig.a import __version__\n",
        "rig/a.py": "__version__ = '1'\n_x = 1\ny = _x\nfrom rig.b import f as _f\n",
        "rig/b.py": "def f():\n    from rig.a import _x\n",
        "rig/c.py": "from .a import _x\nfrom os import _exit\n",
        "rig/_p.py": "",
        "rig/bench/__init__.py": "from rig.bench.run import _spawn, start\n",
        "rig/bench/run.py": "def _spawn():\n    pass\nstart = _spawn\n",
        "daq/__init__.py": "",
        "daq/d.py": "import rig._p\nfrom rig._p import z\nfrom rig import _p\n",
        "daq/e.py": "import rig.bench as rb\nfrom rig import a\nrb._spawn()\na._x\nrb.start()\n"
                    "self = object()\nself._y\n",
        "processing/__init__.py": "",
        "benchmarks/__init__.py": "",
    }
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    assert sorted(crossings(tmp_path)) == [
        ("daq.d", "rig", "_p"),
        ("daq.d", "rig._p", ""),
        ("daq.e", "rig.a", "_x"),
        ("daq.e", "rig.bench", "_spawn"),
        ("rig.b", "rig.a", "_x"),
        ("rig.bench", "rig.bench.run", "_spawn"),
        ("rig.c", "rig.a", "_x"),
    ]
