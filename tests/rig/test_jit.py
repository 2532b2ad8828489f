"""rig._jit: numba is imported when a kernel is first called, not when the modules are imported."""

import json
import subprocess
import sys

import numpy as np


def _run(code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_importing_the_reader_the_analyzer_and_the_bench_does_not_import_numba():
    got = _run("import sys, json\n"
               "import daq.cli, daq.hdf5, daq.acquisition, processing.analysis, rig.bench\n"
               "print(json.dumps('numba' in sys.modules))")
    assert got is False


def test_first_call_materialises_every_kernel_and_patches_the_module_namespaces():
    got = _run(
        "import sys, json\n"
        "import numpy as np\n"
        "import rig.chain as ch, rig.solvers._kernels as it\n"
        "from rig._jit import LazyKernel\n"
        "from rig.accelerometer import _first_order_recursion as f\n"
        "before = isinstance(it.rk4_kernel, LazyKernel)\n"
        "q = f(0.5, np.ones(3), 2.0)\n"
        "print(json.dumps([before, 'numba' in sys.modules, isinstance(it.rk4_kernel, LazyKernel),"
        " type(f).__name__, q.tolist()]))")
    # q[k] = 1 + 0.5 q[k-1] from q[-1] = 2: 2, 2, 2
    assert got == [True, True, False, "LazyKernel", [2.0, 2.0, 2.0]]


def test_a_lazy_kernel_forwards_to_its_dispatcher():
    from rig.accelerometer import _first_order_recursion as f

    q = f(0.25, np.array([1.0, 0.0]), 4.0)
    np.testing.assert_array_equal(q, [2.0, 0.5])
    assert f.py_func(0.25, np.array([1.0, 0.0]), 4.0).tolist() == [2.0, 0.5]
    assert len(f.signatures) >= 1  # a dispatcher attribute, through the lazy object
