"""The packages' layers point one way, rig <- daq <- processing, with the CLI on top, and no
module imports itself round a cycle.

Every import statement of every module is read from its source (ast, function-local imports
included: a lazy import is still a dependency). The rules:

- no cycle among the project's modules (``benchmarks/`` included);
- ``rig`` imports nothing from ``daq``, ``processing`` or ``benchmarks``;
- ``daq`` imports nothing from ``processing`` or ``benchmarks``, except its CLI (the composition
  root: the ``daq.cli`` package);
- ``processing`` imports from ``daq`` only the run-file data contract (:data:`DAQ_CONTRACT`)
  and nothing from ``benchmarks``, except its declared composition sub-layers
  (:data:`SUBLAYERS`, each with its reason), which compose the acquisition with the analysis
  and may import any of ``daq``; nothing else in ``processing`` imports a sub-layer (it sits on
  top); the few other known exceptions are listed, each with its reason, in :data:`EXCEPTIONS`
  (a new one fails);
- a package's public names (``__init__.py``'s lazy exports) come from that package.

Known cycles inside one package that its own restructuring removes are listed in
:data:`KNOWN_CYCLES`; an entry that no longer occurs fails too, so the lists only shrink.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("rig", "daq", "processing", "benchmarks")

#: What processing may import from daq: the stream's data types, the run file's reader (and
#: format), the stepped-sine run file's reader (and format), the sink protocol a consumer
#: implements, the run file's check, and the facade.
DAQ_CONTRACT = ("daq", "daq.records", "daq.hdf5", "daq.sine_file", "daq.sinks", "daq.check")

#: Sub-packages of processing that compose daq's acquisition with the analysis, each with why:
#: they may import any daq module; the rest of processing never imports them.
SUBLAYERS = {
    "processing.dataset": "the dataset runner acquires its runs: a second composition root "
                          "beside the CLI",
    "processing.instrument": "the virtual 35670A measures: it acquires (daq.acquire, pacing, "
                             "run files) and analyses, like the instrument it emulates",
}

#: (importer, imported): the known upward imports, each with why it is there.
EXCEPTIONS: dict = {
    ("processing.sine_sweep", "daq.sine"):
        "the stepped-sine sweep acquires point by point and chooses each next point (auto "
        "resolution, auto level) from the last one's analysis: a composition root like the "
        "dataset runner",
    ("processing.swept_sine", "daq.sine"):
        "the swept sine runs the same acquisition chunk by chunk and hands each point's window "
        "to the sinks as a PointRecord: the stepped sweep's composition root, in its own module",
}

#: Cycles inside one package, each with what removes it (a new cycle fails).
KNOWN_CYCLES: dict = {}


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


def imports_of(name: str, path: Path, known) -> set[str]:
    """The project modules ``name`` (at ``path``) imports anywhere in its source: ``from a.b
    import c`` counts as ``a.b.c`` when that is a module, else as ``a.b``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                here = name.split(".") if is_pkg else name.split(".")[:-1]
                here = here[:len(here) - (node.level - 1)]
                base = ".".join(here + ([node.module] if node.module else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base
                       for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in known:  # "import rig.scene.x" -> the deepest known module
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


def import_graph(root: Path) -> dict[str, set[str]]:
    mods = project_modules(root)
    return {m: imports_of(m, p, mods) for m, p in mods.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
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


def _is_cli(module: str) -> bool:
    return module == "daq.cli" or module.startswith("daq.cli.")


def _sublayer(module: str, sublayers) -> str | None:
    return next((s for s in sublayers if module == s or module.startswith(s + ".")), None)


def upward_imports(graph: dict[str, set[str]], sublayers=None) -> list[str]:
    """One line per import against the layers (see the module docstring); ``sublayers``
    defaults to :data:`SUBLAYERS`."""
    subs = SUBLAYERS if sublayers is None else sublayers
    bad = []
    for m, targets in sorted(graph.items()):
        top = m.split(".")[0]
        for t in sorted(targets):
            layer = t.split(".")[0]
            if (m, t) in EXCEPTIONS:
                continue
            sub_m, sub_t = _sublayer(m, subs), _sublayer(t, subs)
            if top == "processing" and sub_t and sub_t != sub_m:
                bad.append(f"{m} imports {t}: {sub_t} is a composition sub-layer on top of "
                           "processing; nothing below imports it")
                continue
            if top == "processing" and layer == "daq" and sub_m:
                continue
            if top == "rig" and layer in ("daq", "processing", "benchmarks"):
                bad.append(f"{m} imports {t}: rig imports nothing from {layer}")
            elif top == "daq" and layer in ("processing", "benchmarks") and not _is_cli(m):
                bad.append(f"{m} imports {t}: only the CLI composes daq with {layer}")
            elif top == "processing" and layer == "benchmarks":
                bad.append(f"{m} imports {t}: the packages never import benchmarks")
            elif top == "processing" and layer == "daq" and t not in DAQ_CONTRACT:
                bad.append(f"{m} imports {t}: processing imports from daq only the run-file "
                           f"contract ({', '.join(DAQ_CONTRACT)})")
    return bad


def test_no_import_cycle_anywhere():
    found = [c for c in cycles(import_graph(ROOT)) if tuple(c) not in KNOWN_CYCLES]
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def test_layers_point_one_way():
    bad = upward_imports(import_graph(ROOT))
    assert not bad, "\n".join(bad)


def test_every_listed_exception_is_still_needed():
    graph = import_graph(ROOT)
    stale = [f"{m} -> {t}" for m, t in EXCEPTIONS if t not in graph.get(m, ())]
    assert not stale, f"remove from EXCEPTIONS (no longer imported): {stale}"
    composing = {_sublayer(m, SUBLAYERS) for m, ts in graph.items() if _sublayer(m, SUBLAYERS)
                 for t in ts if t.split(".")[0] == "daq" and t not in DAQ_CONTRACT}
    idle = sorted(set(SUBLAYERS) - composing)
    assert not idle, f"remove from SUBLAYERS (they import only the run-file contract): {idle}"
    found = {tuple(c) for c in cycles(graph)}
    gone = [" <-> ".join(c) for c in KNOWN_CYCLES if c not in found]
    assert not gone, f"remove from KNOWN_CYCLES (no longer a cycle): {gone}"


def test_the_check_catches_planted_violations(tmp_path):
    """A tree with a cycle, rig importing daq (function-local), daq importing processing
    outside the CLI, processing importing the acquisition, and processing importing a
    composition sub-layer: each is found; the CLI's own imports, processing's import of the run
    reader and the sub-layer's import of the acquisition are not."""
    files = {
        "rig/__init__.py": "",
        "rig/a.py": "from rig import b\n",
        "rig/b.py": "def f():\n    from .a import g\n",
        "rig/c.py": "def f():\n    import daq.hdf5\n",
        "daq/__init__.py": "",
        "daq/hdf5.py": "from rig.a import x\n",
        "daq/acquisition.py": "from processing.spectra import y\n",
        "daq/cli.py": "from processing import spectra\nfrom daq import acquisition\n",
        "processing/__init__.py": "",
        "processing/spectra.py": "from daq.hdf5 import read_run\n",
        "processing/bad.py": "from daq.acquisition import acquire\n",
        "processing/top/__init__.py": "",
        "processing/top/run.py": "from daq.acquisition import acquire\n",
        "processing/below.py": "from processing.top import run\n",
        "benchmarks/__init__.py": "",
    }
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    graph = import_graph(tmp_path)
    assert cycles(graph) == [["rig.a", "rig.b"]]
    assert upward_imports(graph, {"processing.top": "composes"}) == [
        "daq.acquisition imports processing.spectra: only the CLI composes daq with processing",
        "processing.bad imports daq.acquisition: processing imports from daq only the run-file "
        f"contract ({', '.join(DAQ_CONTRACT)})",
        "processing.below imports processing.top.run: processing.top is a composition "
        "sub-layer on top of processing; nothing below imports it",
        "rig.c imports daq.hdf5: rig imports nothing from daq",
    ]


@pytest.mark.parametrize("package", ["rig", "daq", "processing"])
def test_public_names_resolve_within_their_package(package):
    """Every name of a package's ``__all__`` resolves (the lazy exports point at real objects)
    and is defined in that package."""
    mod = importlib.import_module(package)
    names = getattr(mod, "__all__", [])
    assert names, f"{package}/__init__.py exports nothing"
    for name in names:
        obj = getattr(mod, name)
        home = getattr(obj, "__module__", package) or package
        assert home.split(".")[0] == package, f"{package}.{name} comes from {home}"
