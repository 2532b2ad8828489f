"""The command line starts without the numerics: ``daq --help`` and a command's parse import
neither numpy nor the solvers, and ``daq simulate --method`` still offers every registered
pendulum method."""

import subprocess
import sys
from pathlib import Path

from click.testing import CliRunner

from daq.cli import main
from rig.solvers import PENDULUM, names_for

ROOT = Path(__file__).resolve().parents[2]


def test_daq_help_imports_neither_numpy_nor_the_solvers():
    code = """
import sys
from daq.cli import main
try:
    main(["--help"])
except SystemExit:
    pass
print("LOADED", "numpy" in sys.modules, "rig.solvers" in sys.modules)
"""
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    assert "LOADED False False" in p.stdout.splitlines()


def test_simulate_method_choices_are_the_registrys_pendulum_methods():
    command = main.get_command(None, "simulate")
    method = next(p for p in command.params if p.name == "method")
    assert method.type.choices == tuple(names_for(PENDULUM))
    res = CliRunner().invoke(main, ["simulate", "--help"])
    assert res.exit_code == 0 and "[" + "|".join(names_for(PENDULUM)) + "]" in res.output
    res = CliRunner().invoke(main, ["simulate", "ishizaki2009", "--duration", "1",
                                    "--method", "euler", "--out", "x.csv"])
    assert res.exit_code == 2 and "'euler' is not one of 'rk4'" in res.output
