"""The README's Python works as written: its library paths resolve after ``import rig, daq,
processing``, and its ```python blocks run, in order, in a fresh interpreter in an empty
directory (the files a block reads are made the way the README says they are made; a block that
needs what this machine cannot give is listed with the reason)."""

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")

#: ``daq.hdf5.read_run``-like paths in the README's backticks (private segments are references
#: to a file, not a path to use)
PATH = re.compile(r"`((?:rig|daq|processing)(?:\.[A-Za-z]\w*)+)")


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, re.S)


def _run(code: str, cwd: Path, timeout: float = 600.0) -> subprocess.CompletedProcess:
    env = dict(os.environ, HF_HOME=str(cwd / "hf"), HF_DATASETS_OFFLINE="1", MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env)


def test_readme_library_paths_resolve_as_a_reader_imports_them(tmp_path):
    paths = sorted(set(PATH.findall(README)))
    for named in ("daq.hdf5.read_run", "daq.check.check_file", "processing.dataset.run_sweep",
                  "processing.live_view.LiveView"):
        assert named in paths or named in README, named
        paths.append(named)
    code = textwrap.dedent(f"""
        import importlib
        bad = []
        for path in {sorted(set(paths))!r}:
            parts = path.split(".")
            for k in range(len(parts), 0, -1):  # the longest prefix that is a module
                try:
                    obj = importlib.import_module(".".join(parts[:k]))
                    break
                except ImportError:
                    continue
            for part in parts[k:]:
                try:
                    obj = getattr(obj, part)
                except AttributeError as exc:
                    bad.append(f"{{path}}: {{exc}}")
                    break
        print("\\n".join(bad))
        """)
    out = _run(code, tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", out.stdout


#: Every README python block, by its first line: the code that makes the files it reads, run
#: before it (``None``: the block is not run here, the reason says why). The blocks run in one
#: fresh interpreter, in README order, in an empty directory.
CLI = "from click.testing import CliRunner\nfrom daq.cli import main as _daq\n"
BEFORE = {
    "import daq, processing, rig": "",
    "import h5py": "processing.write_spectra(analysis, 'spectra.h5')\n",
    "import xarray as xr": textwrap.dedent("""
        from concurrent.futures import ThreadPoolExecutor
        from processing.dataset import parse_sweep, run_sweep
        sweep = parse_sweep({
            "seed": 1, "scene": "ishizaki2009",
            "set": ["acquisition.records=2", "acquisition.record_s=20",
                    "acquisition.settle_s=10"],
            "grid": {"source.level_vrms": [0.05, 0.1]},
            "analysis": {"nperseg": 1000}})
        with ThreadPoolExecutor(1) as pool:
            result = run_sweep(sweep, "ds", executor=pool, workers=1)
        """),
    "from datasets import load_dataset": CLI + textwrap.dedent("""
        for fmt, out in (("parquet", "ds_parquet"), ("npz", "ds_npz")):
            res = CliRunner().invoke(_daq, ["dataset", "export", "ds", "--out", out, "--format",
                                            fmt, "--split", "train=1"])
            assert res.exit_code == 0, res.output
        """),
    "from processing.sine_sweep import SineSettings, measure_sine": "",
    "import pyvisa": textwrap.dedent("""
        import threading
        from processing.instrument.analyzer35670a import Analyzer35670A
        from processing.instrument.server import ScpiServer
        _srv = ScpiServer(Analyzer35670A(rig.load_scene("ishizaki2009"), seed=1), "127.0.0.1",
                          5025)  # what `daq serve ishizaki2009` runs, in a thread here
        threading.Thread(target=_srv.serve_forever, daemon=True).start()
        """),
    "from processing.dataset import open_zarr_index": None,  # its second half reads an S3 bucket
    "import daq, processing.bla as bla, rig": "",
    "import numpy as np, nonlinear_benchmarks as nb": CLI + textwrap.dedent("""
        res = CliRunner().invoke(_daq, ["export", "run.h5", "--sysid", "sysid.npz"])
        assert res.exit_code == 0, res.output
        """),
    "import numpy as np": CLI + textwrap.dedent("""
        res = CliRunner().invoke(_daq, ["export", "run.h5", "--oma", "oma.npz"])
        assert res.exit_code == 0, res.output
        """),
}
SKIPPED = {"from processing.dataset import open_zarr_index":
           "its second half opens an S3 bucket with credentials"}


def test_readme_python_blocks_run_in_order_as_written(tmp_path):
    """Every block whose files can be made here runs as written; a new block must be added to
    BEFORE (what makes its files) before this passes."""
    script, ran = [], []
    for block in python_blocks(README):
        first = block.splitlines()[0].split("#")[0].strip()
        assert first in BEFORE, f"a new README block, {first!r}: say in BEFORE what it needs"
        if BEFORE[first] is None:
            assert first in SKIPPED
            continue
        script += [BEFORE[first], block, f"print('ran: ' + {first!r})\n"]
        ran.append(first)
    assert len(ran) >= 3
    out = _run("".join(script), tmp_path, timeout=1200)
    assert out.returncode == 0, out.stderr[-3000:]
    assert [ln[5:] for ln in out.stdout.splitlines() if ln.startswith("ran: ")] == ran
