"""rig.jit: numba is imported when a kernel is first called, not when the modules are imported."""

import json
import subprocess
import sys

import numpy as np


def _run(code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_importing_the_reader_the_analyzer_and_the_bench_does_not_import_numba():
    got = _run("import sys, json\n"
               "import daq.cli, daq.hdf5, daq.acquisition, processing.analyzer, rig.bench\n"
               "print(json.dumps('numba' in sys.modules))")
    assert got is False


def test_first_call_materialises_every_kernel_and_patches_the_module_namespaces():
    got = _run(
        "import sys, json\n"
        "import numpy as np\n"
        "import rig.chain as ch, rig.solvers.rk4 as it\n"
        "from rig.jit import LazyKernel\n"
        "from rig.devices.accelerometer import _first_order_recursion as f\n"
        "before = isinstance(it.rk4_kernel, LazyKernel)\n"
        "q = f(0.5, np.ones(3), 2.0)\n"
        "print(json.dumps([before, 'numba' in sys.modules, isinstance(it.rk4_kernel, LazyKernel),"
        " type(f).__name__, q.tolist()]))")
    # q[k] = 1 + 0.5 q[k-1] from q[-1] = 2: 2, 2, 2
    assert got == [True, True, False, "LazyKernel", [2.0, 2.0, 2.0]]


def test_a_lazy_kernel_forwards_to_its_dispatcher():
    from rig.devices.accelerometer import _first_order_recursion as f

    q = f(0.25, np.array([1.0, 0.0]), 4.0)
    np.testing.assert_array_equal(q, [2.0, 0.5])
    assert f.py_func(0.25, np.array([1.0, 0.0]), 4.0).tolist() == [2.0, 0.5]
    assert len(f.signatures) >= 1  # a dispatcher attribute, through the lazy object


def test_the_cache_directory_is_keyed_by_every_kernel_source(tmp_path, monkeypatch):
    """numba's cache checks a kernel's own file only; rig.jit keys the whole cache by a hash of
    every kernel file, so a change in a callee's file (rig.solvers.primitives, called from rig.chain
    and rig.solvers.coupled) starts a fresh cache."""
    import rig.chain  # noqa: F401  (registers kernels that call rig.solvers.primitives)
    import rig.solvers.coupled  # noqa: F401
    from rig import jit

    names = {p.relative_to(p.parents[1]).as_posix() for p in jit.kernel_sources()}
    assert {"rig/chain.py", "solvers/coupled.py", "solvers/primitives.py"} <= names
    src = tmp_path / "k.py"
    src.write_text("@njit(cache=True)\ndef f(x):\n    return x + 1.0\n")
    monkeypatch.setattr(jit, "kernel_sources", lambda: [src])
    before = jit.cache_dir()
    assert before == jit.cache_dir()  # a pure function of the sources
    src.write_text("@njit(cache=True)\ndef f(x):\n    return x + 2.0\n")
    after = jit.cache_dir()
    assert after != before and after.parent == before.parent


def test_the_lazy_loader_names_no_package_of_its_own():
    """rig.jit patches the packages of the registered kernels (found at run time), never a
    package named in its source (rig must not know daq or processing)."""
    from pathlib import Path

    import rig.jit

    text = Path(rig.jit.__file__).read_text()
    assert '"daq"' not in text and '"processing"' not in text


def test_a_new_cache_directory_prunes_old_siblings_but_keeps_recent_and_newest(tmp_path):
    import os
    import time

    from rig import jit

    now = time.time()
    ages_days = {"numba-a": 10, "numba-b": 9, "numba-c": 8, "numba-d": 7, "numba-e": 0.5,
                 "numba-f": 30}
    for name, days in ages_days.items():
        d = tmp_path / name
        d.mkdir()
        (d / "kernel.nbi").write_bytes(b"x")
        os.utime(d, (now - days * 86400, now - days * 86400))
    (tmp_path / "other").mkdir()  # not a kernel cache: never touched
    current = tmp_path / "numba-new"
    removed = jit.prune_cache_dirs(current, keep=2, min_age_s=86400)
    # kept: the two newest (e, d), and none younger than a day besides; removed the rest
    assert sorted(p.name for p in removed) == ["numba-a", "numba-b", "numba-c", "numba-f"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["numba-d", "numba-e", "other"]
