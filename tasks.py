#!/usr/bin/env python3
"""Set up the project's virtual environment and run its jobs, with nothing but Python 3.11 and pip.

    python3 tasks.py experiment   # the paper's experiment end to end (outputs in out/)
    python3 tasks.py test         # the test suite
    python3 tasks.py setup        # only the environments (what ``test`` makes first)
    python3 tasks.py setup-system # as root: the Debian packages some tests use (apt-get)

Extra arguments go to the job's last command: ``python3 tasks.py test -k analysis``,
``python3 tasks.py experiment --window uniform`` (to ``daq analyze``).

The environment is ``.venv`` beside this file, created (and the package installed into it with
every extra: EXTRAS) on first use and refreshed when ``pyproject.toml`` changes; ``test`` also
makes ``.venv-compat`` (an older h5py, to read the project's files with). Nothing outside this
directory is installed except by ``setup-system``, which CI runs (``.ci/run``); without its
packages the tests that need them skip, saying which package is missing.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
PY = VENV / "bin" / "python"
STAMP = VENV / ".pendulum-daq-installed"


def run(*cmd, **kw) -> None:
    print("+", " ".join(str(c) for c in cmd), flush=True)
    subprocess.run([str(c) for c in cmd], check=True, cwd=ROOT, **kw)


#: the package's extras ``.venv`` gets: every optional feature, and what the tests use
EXTRAS = ("test", "plot", "uff", "xarray", "dask", "ml", "zarr")


def ensure_venv() -> None:
    pyproject = (ROOT / "pyproject.toml").read_bytes()
    want = hashlib.sha256(pyproject + repr(EXTRAS).encode()).hexdigest()
    if STAMP.exists() and STAMP.read_text() == want and PY.exists():
        return
    if not PY.exists():
        try:
            run(sys.executable, "-m", "venv", VENV)
        except subprocess.CalledProcessError:
            # Debian's python3 without python3-venv has no ensurepip: make the venv bare and let
            # the system pip install into it.
            run(sys.executable, "-m", "venv", "--clear", "--without-pip", VENV)
    has_pip = subprocess.run([str(PY), "-m", "pip", "--version"], capture_output=True).returncode == 0
    pip = [PY, "-m", "pip"] if has_pip else [sys.executable, "-m", "pip", "--python", PY]
    print(f"installing pendulum-daq and its dependencies into {VENV.name} (once, a few minutes)",
          flush=True)
    t0 = time.monotonic()
    with elapsed_lines("installing"):
        rc = subprocess.run([str(c) for c in (*pip, "install", "--disable-pip-version-check",
                                              "-q", "-e", f".[{','.join(EXTRAS)}]")],
                            cwd=ROOT).returncode
    if rc:
        raise SystemExit(f"pip could not install pendulum-daq into {VENV.name} (exit status "
                         f"{rc}; its messages are above); fix that and run this again")
    print(f"installed in {_minutes(time.monotonic() - t0)}", flush=True)
    STAMP.write_text(want)


#: Seconds between the lines that say a long, quiet step is still running.
TICK_S = 30.0


def _minutes(s: float) -> str:
    return f"{s:.0f} s" if s < 90 else f"{s / 60:.1f} min"


@contextlib.contextmanager
def elapsed_lines(what: str, every_s: float = TICK_S):
    """While the block runs, print ``"  still <what>: <elapsed>"`` every ``every_s`` seconds
    (pip's quiet install prints nothing for minutes)."""
    stop = threading.Event()
    t0 = time.monotonic()

    def tick():
        while not stop.wait(every_s):
            print(f"  still {what}: {_minutes(time.monotonic() - t0)}", flush=True)

    t = threading.Thread(target=tick, name="elapsed", daemon=True)
    t.start()
    try:
        yield
    finally:
        stop.set()
        t.join()


COMPAT_VENV = ROOT / ".venv-compat"
COMPAT_H5PY = "h5py==3.11.0"  # bundles HDF5 1.14: the older readers the file tests open files with


def install_reader_tools() -> None:
    """An older h5py (HDF5 1.14) in its own environment ``.venv-compat``, one of the readers the
    file-compatibility tests open the project's files with besides those of the test extra. Best
    effort and done once: if it cannot be installed, the tests that need it skip saying why."""
    stamp = COMPAT_VENV / ".installed"
    if stamp.exists() and stamp.read_text() == COMPAT_H5PY:
        return
    cpy = COMPAT_VENV / "bin" / "python"
    ok = subprocess.run([sys.executable, "-m", "venv", "--clear", COMPAT_VENV], cwd=ROOT,
                        capture_output=True).returncode == 0
    ok = ok and subprocess.run([str(cpy), "-m", "pip", "install", "--disable-pip-version-check",
                                "-q", COMPAT_H5PY, "numpy<2.1"], cwd=ROOT,
                               capture_output=True).returncode == 0
    if ok:
        stamp.write_text(COMPAT_H5PY)


def compile_bytecode() -> None:
    """Byte-compile the project's packages (what a non-editable install does): with
    PYTHONDONTWRITEBYTECODE set, as on some CI machines, every ``daq`` command would otherwise
    recompile ~40 modules at start-up (~0.2 s). Up-to-date files are skipped."""
    subprocess.run([str(PY), "-m", "compileall", "-q", "rig", "daq", "processing"], check=True,
                   cwd=ROOT, stdout=subprocess.DEVNULL)


#: Debian packages some tests use, installed only by ``setup-system`` (as root, with apt-get):
#: HDF5 1.10's command-line tools (h5dump, h5clear) for the file-compatibility tests, and an X
#: server in memory with Mesa's software Vulkan for the live view's screenshot test. Without them
#: those tests skip saying why.
SYSTEM_PACKAGES = ("hdf5-tools", "xvfb", "xauth", "mesa-vulkan-drivers", "libvulkan1")


def setup_system() -> int:
    """Install SYSTEM_PACKAGES with apt-get; says what it does and refuses without root."""
    import shutil

    if os.name != "posix" or shutil.which("apt-get") is None:
        print("setup-system needs a Debian-like system with apt-get; the tests that use "
              f"{', '.join(SYSTEM_PACKAGES)} will skip", file=sys.stderr)
        return 1
    if os.geteuid() != 0:
        print(f"setup-system installs the Debian packages {' '.join(SYSTEM_PACKAGES)} with "
              "apt-get and must run as root (sudo python3 tasks.py setup-system)",
              file=sys.stderr)
        return 1
    print(f"installing the Debian packages {' '.join(SYSTEM_PACKAGES)} (apt-get)", flush=True)
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    try:
        run("apt-get", "update", "-q", env=env, stdout=subprocess.DEVNULL)
        run("apt-get", "install", "-y", "-q", "--no-install-recommends", *SYSTEM_PACKAGES,
            env=env, stdout=subprocess.DEVNULL)
    except subprocess.CalledProcessError as exc:
        print(f"could not install {' '.join(SYSTEM_PACKAGES)}: {exc}; the tests that use them "
              "will skip", file=sys.stderr)
        return 1
    return 0


DAQ = [PY, "-m", "daq.cli"]

# The paper's experiment end to end (SPEC section 1): 30 records of 100 s of the emulated bench,
# then the analyzer against the exact model, and the model's own Bode diagrams. Outputs in out/.
EXPERIMENT = [
    [*DAQ, "acquire", "--scene", "ishizaki2009", "--records", "30", "--duration", "100",
     "--seed", "2009", "--out", "out/paper_run.h5", "--force"],
    [*DAQ, "model", "ishizaki2009", "--csv", "out/model.csv", "--plot", "out/bode_model.png",
     "--force"],
    [*DAQ, "analyze", "out/paper_run.h5", "--csv", "out/frf.csv", "--plot", "out/bode.png",
     "--report", "out/report.md", "--spectra", "out/spectra.h5", "--force"],
]


def check_extra_args(cmd: list, extra: list[str], env: dict) -> int:
    """Parse the last ``daq`` command with the extra arguments before any step runs
    (``daq.cli.parse_only``), so that a misspelt option is refused before the acquisition, not
    after it. Its run file may not exist yet: this file stands in for it while parsing."""
    args = [str(c) for c in cmd[len(DAQ):]]
    args = [args[0], str(Path(__file__).resolve()), *args[2:], *extra]
    return subprocess.run([str(PY), "-c", "import sys; from daq.cli import parse_only; "
                           "sys.exit(parse_only(sys.argv[1:]))", *args], cwd=ROOT,
                          env=env).returncode


def test_workers() -> list[str]:
    """The whole suite runs in one pytest process per core, up to four (pytest-xdist), each
    test file in one process (``--dist loadfile``: a file's module fixtures are built once)."""
    n = min(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
            else os.cpu_count() or 1, 4)
    return ["-n", str(n), "--dist", "loadfile"] if n > 1 else []


def main(argv: list[str]) -> int:
    """Run a job: its commands in sequence, stopping at the first failure; extra args go to the
    job's last command (``daq analyze`` for the experiment, pytest for the tests)."""
    jobs = {
        "experiment": EXPERIMENT,
        "test": [[PY, "-m", "pytest", "-q"]],
        "setup": [],
    }
    if len(argv) < 1 or argv[0] not in (*jobs, "setup-system"):
        print(f"usage: python3 tasks.py {{{','.join(jobs)},setup-system}} [extra args]",
              file=sys.stderr)
        return 2
    if argv[0] == "setup-system":
        return setup_system()
    ensure_venv()
    if argv[0] in ("test", "setup"):
        install_reader_tools()
    compile_bytecode()
    cmds = jobs[argv[0]]
    if not cmds:
        return 0
    (ROOT / "out").mkdir(exist_ok=True)
    env = dict(os.environ, PYTHONHASHSEED="0")
    if argv[0] == "experiment" and argv[1:]:
        rc = check_extra_args(cmds[-1], argv[1:], env)
        if rc:
            return rc
    if argv[0] == "test" and not argv[1:]:
        cmds = [[*cmds[0], *test_workers()]]
    for i, cmd in enumerate(cmds):
        cmd = [str(c) for c in cmd] + (argv[1:] if i == len(cmds) - 1 else [])
        if len(cmds) > 1:
            print("+", " ".join(c if c != str(PY) else "python" for c in cmd), flush=True)
        rc = subprocess.run(cmd, cwd=ROOT, env=env).returncode
        if rc:
            return rc
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
