"""The README's Python works as written: its library paths resolve after ``import rig, daq,
processing``, and its ```python blocks run, in order, in a fresh interpreter in an empty
directory (the files a block reads are made the way the README says they are made)."""

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
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)


def test_readme_library_paths_resolve_after_importing_the_packages(tmp_path):
    paths = sorted(set(PATH.findall(README)))
    for named in ("daq.hdf5.read_run", "daq.check.check_file", "processing.dataset.run_sweep",
                  "processing.live_view.LiveView"):
        assert named in paths or named in README, named
        paths.append(named)
    code = textwrap.dedent(f"""
        import rig, daq, processing
        bad = []
        for path in {sorted(set(paths))!r}:
            obj = {{"rig": rig, "daq": daq, "processing": processing}}[path.split(".")[0]]
            for part in path.split(".")[1:]:
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


def test_readme_python_blocks_run_in_order_as_written(tmp_path):
    """Block 1 acquires and analyses ``run.h5`` (4 records); block 2 reads it and the
    ``spectra.h5`` that ``daq analyze --spectra`` writes (``processing.write_spectra``); block 3
    opens a sweep's manifest, here a 2-run sweep of short records made with ``run_sweep``."""
    blocks = python_blocks(README)
    assert len(blocks) == 3, "a new README block: say here what its files need"
    between = [
        "processing.write_spectra(analysis, 'spectra.h5')\n",
        textwrap.dedent("""
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
    ]
    script = blocks[0] + between[0] + blocks[1] + between[1] + blocks[2]
    script += "\nassert int(ok.sizes['run']) == 2, ok\nprint('ran')\n"
    out = _run(script, tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip().endswith("ran")
