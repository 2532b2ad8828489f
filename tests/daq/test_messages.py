"""What a person reads when something is wrong: options and outputs refused before any work, no
exception class name in any message, library refusals that name no command-line flag (the
command line adds its own), one exit-code table. Real CLI in subprocesses, bounded in time."""

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cli_runs import FAST, daq, fast_run
from daq.cli.errors import EXIT_CODES

ROOT = Path(__file__).resolve().parents[2]
#: an exception class name as Python prints it (FooError, KeyboardInterrupt, ...)
CLASS_NAME = re.compile(r"\b[A-Z][A-Za-z]*(Error|Exception|Interrupt|Warning)\b")
SWEEP = """seed = 1
scene = "ishizaki2009"
set = ["acquisition.records=2", "acquisition.record_s=10", "acquisition.settle_s=5",
       "acquisition.model=linear"]
[grid]
"pendulum.q1" = [300.0]
"""


def one_line_error(res, code=1):
    """The command failed with ``code`` and one line ``Error: ...`` naming no class."""
    assert res.returncode == code, (res.returncode, res.stdout, res.stderr)
    lines = [s for s in res.stderr.splitlines() if s.strip()]
    assert lines[-1].startswith("Error: ") and "Traceback" not in res.stderr, res.stderr
    assert not CLASS_NAME.search(res.stderr), res.stderr
    return lines[-1]


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    return fast_run(tmp_path_factory.mktemp("run"))


# -- validated before any work ---------------------------------------------------------------

def test_a_bad_uff_name_is_refused_before_the_csv_is_written(run_file, tmp_path):
    t0 = time.monotonic()
    res = daq("analyze", run_file, "--csv", "f.csv", "--uff", "frf.txt", cwd=tmp_path)
    assert res.returncode == 2 and "--uff" in res.stderr and ".uff, .unv" in res.stderr
    assert list(tmp_path.iterdir()) == [] and time.monotonic() - t0 < 60
    res = daq("export", run_file, "--out", "eu.txt", cwd=tmp_path)
    assert res.returncode == 2 and ".nc, .h5, .hdf5" in res.stderr


def test_the_experiment_refuses_a_misspelt_option_before_acquiring():
    run = ROOT / "out" / "paper_run.h5"
    before = run.stat().st_mtime_ns if run.exists() else None
    t0 = time.monotonic()
    res = subprocess.run([sys.executable, "tasks.py", "experiment", "--windw", "hann"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 2, res.stdout + res.stderr
    assert "No such option '--windw'" in res.stderr and "--window" in res.stderr
    assert "acquire" not in res.stdout  # no step ran
    assert (run.stat().st_mtime_ns if run.exists() else None) == before
    assert time.monotonic() - t0 < 120


# -- no class names, sentences that say what to do ---------------------------------------------

def test_a_deep_chain_of_base_scenes_is_refused_with_its_limit(tmp_path):
    (tmp_path / "s0.toml").write_text('base = "ishizaki2009"\n')
    for i in range(1, 1001):
        (tmp_path / f"s{i}.toml").write_text(f'base = "s{i - 1}.toml"\n')
    line = one_line_error(daq("scene", "show", "s1000.toml", cwd=tmp_path))
    assert "its chain of bases is deeper than 32" in line and "s1000.toml" in line
    assert daq("scene", "show", "s30.toml", cwd=tmp_path).returncode == 0  # 31 files + preset


def test_numbers_with_hundreds_or_thousands_of_digits_are_named_by_their_size(tmp_path):
    line = one_line_error(daq("scene", "show", "ishizaki2009", "--set",
                              "pendulum.q1=1" + "0" * 400, cwd=tmp_path))
    assert line == ("Error: pendulum.q1 = an integer of about 401 digits is invalid: expected a "
                    "finite number")
    line = one_line_error(daq("scene", "show", "ishizaki2009", "--set",
                              "pendulum.q1=-1" + "0" * 5000, cwd=tmp_path))
    assert "pendulum.q1: the value -10000000000..." in line and "4300 digits" in line
    line = one_line_error(daq("scene", "show", "rod-chain", "--set",
                              "pendulum.n=1" + "0" * 400, cwd=tmp_path))
    assert "n = an integer of about 401 digits is invalid: expected 1 <= n <= 200" in line


@pytest.mark.parametrize("command", ["acquire", "analyze", "export"])
def test_an_output_on_a_dangling_link_is_refused_without_force_and_replaced_with_it(
        run_file, tmp_path, command):
    name = {"acquire": "run.h5", "analyze": "frf.csv", "export": "eu.nc"}[command]
    link = tmp_path / name
    os.symlink(tmp_path / "nowhere" / "x", link)
    args = {"acquire": ["acquire", "ishizaki2009", *FAST, "--out", name],
            "analyze": ["analyze", run_file, "--csv", name],
            "export": ["export", run_file, "--out", name]}[command]
    line = one_line_error(daq(*args, cwd=tmp_path, timeout=300))
    assert line == (f"Error: output {name!r} is a symbolic link to "
                    f"{str(tmp_path / 'nowhere' / 'x')!r}, which does not exist; pass --force "
                    "to replace the link by the file")
    assert link.is_symlink()
    res = daq(*args, "--force", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    assert not link.is_symlink() and link.is_file() and link.stat().st_size > 0


def test_library_refusals_name_no_flag_and_the_command_line_adds_it(tmp_path):
    from rig.output_files import check_writable
    from rig.errors import ForceRequired

    (tmp_path / "m.csv").write_text("x")
    with pytest.raises(ForceRequired) as info:
        check_writable(tmp_path / "m.csv", force=False)
    assert "--" not in str(info.value) and info.value.action == "overwrite it"
    line = one_line_error(daq("model", "ishizaki2009", "--csv", "m.csv", cwd=tmp_path))
    assert line == "Error: output 'm.csv' exists; pass --force to overwrite it"


def test_a_damaged_sweep_journal_or_plan_says_the_sweep_cannot_be_resumed(tmp_path):
    (tmp_path / "s.toml").write_text(SWEEP)
    res = daq("dataset", "s.toml", "--out", "ds", "--workers", "1", cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    journal, plan = tmp_path / "ds" / "journal.jsonl", tmp_path / "ds" / "sweep.json"
    good_journal, good_plan = journal.read_bytes(), plan.read_bytes()
    for damage in (b"\xff\xfe not text\n", b"[1, 2]\n" + good_journal, b"{oops\n" + good_journal):
        journal.write_bytes(damage)
        line = one_line_error(daq("dataset", "s.toml", "--out", "ds", cwd=tmp_path))
        assert "journal.jsonl' is damaged" in line and "cannot be resumed" in line
        assert "move it aside and run again" in line
    journal.write_bytes(good_journal)
    for damage in (b"{not json", b"[]", b'{"sweep": 3}'):
        plan.write_bytes(damage)
        line = one_line_error(daq("dataset", "s.toml", "--out", "ds", cwd=tmp_path))
        assert "sweep.json' is damaged" in line and "cannot be resumed" in line
        assert "new output directory" in line
    plan.write_bytes(good_plan)
    res = daq("dataset", "s.toml", "--out", "ds", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr  # resumed: nothing to redo


def test_sweep_messages_name_the_distribution_and_no_class(tmp_path):
    (tmp_path / "typo.toml").write_text(SWEEP.replace(
        '"pendulum.q1" = [300.0]', '"pendulum.q1" = [300.0]\n[random]\n'
        '"stage.damping_nspm" = { unifrom = [0.5, 2.0] }'))
    line = one_line_error(daq("dataset", "typo.toml", "--out", "ds", "--dry-run", cwd=tmp_path))
    assert line == ("Error: random.stage.damping_nspm: unknown distribution 'unifrom'; valid: "
                    "uniform, loguniform, normal (normal with optional bounds), e.g. "
                    "{ uniform = [0.5, 2.0] }")
    (tmp_path / "bad.toml").write_text(SWEEP.replace("[300.0]", "[300.0, -1.0]"))
    res = daq("dataset", "bad.toml", "--out", "ds", "--dry-run", cwd=tmp_path)
    assert "invalid: pendulum.q1 = -1.0 is invalid: expected > 0" in res.stdout
    assert not CLASS_NAME.search(res.stdout + res.stderr)


# -- one exit-code table -----------------------------------------------------------------------

def test_the_exit_codes_are_one_table_in_help_and_readme(tmp_path):
    res = daq("--help", cwd=tmp_path, timeout=60)
    readme = (ROOT / "README.md").read_text()
    for code, meaning in EXIT_CODES:
        assert re.search(rf"^\s+{re.escape(code)}\s+{re.escape(meaning)}$", res.stdout, re.M), code
        assert f"| {code} | {meaning} |" in readme, code
