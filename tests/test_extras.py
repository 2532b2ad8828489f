"""Optional features are extras of the package (plot, uff, xarray, dask): without one, the
commands that need it say which extra to install, and the others work."""

import subprocess
import sys

import pytest

from rig.errors import MissingExtraError, RigError, import_extra


def test_a_missing_extra_is_named_with_the_install_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyuff", None)  # as if not installed
    with pytest.raises(MissingExtraError) as err:
        import_extra("pyuff", "uff", "writing UFF files")
    assert str(err.value) == ("writing UFF files needs pyuff, which is not installed: "
                              "pip install 'pendulum-daq[uff]'")
    assert isinstance(err.value, RigError) and isinstance(err.value, ImportError)


def test_a_module_missing_inside_an_installed_extra_is_not_blamed_on_the_extra(tmp_path,
                                                                              monkeypatch):
    (tmp_path / "half_installed.py").write_text("import not_a_module_anywhere\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="not_a_module_anywhere"):
        import_extra("half_installed", "plot", "drawing figures")


def _daq_without(module: str, *args: str, cwd) -> subprocess.CompletedProcess:
    code = (f"import sys; sys.modules[{module!r}] = None\n"
            "from daq.cli import run\n"
            f"sys.argv = ['daq', *{list(args)!r}]\n"
            "run()\n")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_without_matplotlib_a_plot_says_which_extra_and_the_csv_is_still_written(tmp_path):
    res = _daq_without("matplotlib", "model", "ishizaki2009", "--csv", "m.csv", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "m.csv").stat().st_size > 0
    res = _daq_without("matplotlib", "model", "ishizaki2009", "--plot", "b.png", cwd=tmp_path)
    assert res.returncode == 1
    assert res.stderr.strip().splitlines()[-1] == (
        "Error: drawing figures needs matplotlib, which is not installed: "
        "pip install 'pendulum-daq[plot]'")
    assert not (tmp_path / "b.png").exists() and "Traceback" not in res.stderr
