"""``daq check`` and the checks ``daq inspect`` and ``daq analyze`` share (daq.check.check_file):
a sound file passes, a truncated or corrupt one is named as such at once (never a hang, never
"complete"), analyze refuses it or with --allow-incomplete uses only the records that verify, and
older files are still read. Every CLI case runs the real CLI in a subprocess."""

import json
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from daq.check import FileCheck, MissingFile, check_file
from daq.hdf5 import read_run
from faults import record_fault, record_inputs

SHORT = ["--scene", "ishizaki2009", "--records", "3", "--duration", "5", "--rate", "100",
         "--set", "acquisition.settle_s=5"]


def daq(*args, cwd, timeout=60):
    """The real CLI in a subprocess (SIGINT restored); a hang fails the test at ``timeout``."""
    return subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


@pytest.fixture(scope="module")
def sound(tmp_path_factory):
    d = tmp_path_factory.mktemp("check")
    res = daq("acquire", *SHORT, "--seed", "11", "--out", "run.h5", "-q", cwd=d, timeout=300)
    assert res.returncode == 0, res.stderr
    res = daq("simulate", "double-rod", "--duration", "1", "--method", "rk4", "--dt", "0.01",
              "--out", "trajectory.h5", cwd=d, timeout=300)
    assert res.returncode == 0, res.stderr
    return d


def _copy(sound, tmp_path, name="run.h5"):
    p = tmp_path / name
    shutil.copy(sound / name, p)
    return p


def _flip_chunk(path, dataset, record):
    """Flip one byte in the middle of the stored chunk of ``record`` of ``dataset``."""
    with h5py.File(path, "r") as f:
        info = f[dataset].id.get_chunk_info_by_coord((record,) + (0,) * (f[dataset].ndim - 1))
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        b = fh.read(1)
        fh.seek(info.byte_offset + info.size // 2)
        fh.write(bytes([b[0] ^ 0xFF]))


def test_a_sound_run_and_trajectory_file_pass(sound):
    res = daq("check", "run.h5", "trajectory.h5", cwd=sound)
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stdout.splitlines() == [
        "run.h5: OK run, complete, 3 of 3 records verify, format 1.2",
        "trajectory.h5: OK trajectory, complete, format 1.1"]
    got = json.loads(daq("check", "run.h5", "--json", cwd=sound).stdout)
    assert got == [{"path": "run.h5", "kind": "run", "ok": True, "status": "complete",
                    "records_valid": 3, "records_planned": 3, "format_version": "1.2",
                    "problems": [], "notes": [], "bad_records": [], "records_complete": 3}]


@pytest.mark.parametrize("keep", [1 / 3, 0.9, -100])
def test_a_truncated_file_is_named_truncated_at_once_by_check_inspect_and_analyze(
        sound, tmp_path, keep):
    src = (sound / "run.h5").read_bytes()
    n = int(len(src) * keep) if keep > 0 else len(src) + keep
    p = tmp_path / "cut.h5"
    p.write_bytes(src[:n])
    t = time.perf_counter()
    fc = check_file(p)
    assert time.perf_counter() - t < 1.0
    assert not fc.ok and fc.status == "truncated" and fc.records_valid is None
    assert fc.problems == (f"truncated: {n} of the {len(src)} bytes its HDF5 superblock records "
                           f"({len(src) - n} missing); no HDF5 reader opens it",)
    for args in (["check", p], ["inspect", p], ["analyze", p], ["analyze", p,
                                                                  "--allow-incomplete"]):
        res = daq(*args, cwd=tmp_path, timeout=30)
        assert res.returncode == 1, (args, res.stdout, res.stderr)
        out = res.stdout + res.stderr
        assert "truncated" in out and "Traceback" not in out and "complete," not in out
        assert len(out.strip().splitlines()) == 1, out
    record_fault("run file truncated (1/3, 90 %, last 100 bytes cut)", records_lost=0,
                 outcome="check, inspect, analyze: one line 'truncated', exit 1, < 1 s")


def test_a_corrupt_record_is_named_and_analyze_refuses_or_leaves_it_out(sound, tmp_path):
    p = _copy(sound, tmp_path)
    _flip_chunk(p, "entry/data/x", 1)
    res = daq("check", p, cwd=tmp_path)
    assert res.returncode == 1
    assert res.stdout.strip() == (f"{p}: BAD run, corrupt, 2 of 3 records verify, format 1.2; "
                                  "entry/data/x: record 1 fails the checksum (corrupt data)")
    res = daq("inspect", p, cwd=tmp_path)
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert ("status: CORRUPT: 2 of 3 records verify; entry/data/x: record 1 fails the checksum"
            in res.stdout) and "complete, 3 of 3" not in res.stdout
    res = daq("analyze", p, cwd=tmp_path)
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert res.stderr.strip().endswith("--allow-incomplete analyses the 2 records that verify")
    res = daq("analyze", p, "--allow-incomplete", cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "analysing the 2 records that verify" in res.stderr
    assert "2 of 3 records" in res.stdout
    # the records analysed are the sound ones, bit for bit
    whole, part = read_run(sound / "run.h5"), read_run(p, records=check_file(p).valid_records)
    for c in ("a", "x", "y"):
        np.testing.assert_array_equal(part.codes[c], whole.codes[c][[0, 2]])
    record_fault("a byte of one record flipped", records_lost=0,
                 outcome="check/inspect: 'corrupt', the record named, exit 1; analyze refuses, "
                         "--allow-incomplete uses the 2 sound records")


def test_fewer_rows_than_records_complete_counts_is_named_truncated(sound, tmp_path):
    p = _copy(sound, tmp_path)
    with h5py.File(p, "r+") as f:
        f["entry/data/y"].resize(2, axis=0)
    fc = check_file(p)
    assert not fc.ok and fc.status == "truncated" and fc.bad_records == (2,)
    assert "entry/data/y holds 2 rows but records_complete = 3" in fc.problems
    assert fc.valid_records == (0, 1)


def _extra_row(p, status):
    """One dataset one row longer than records_complete (the record being written), the status
    set as the writer's stop sets it."""
    with h5py.File(p, "r+") as f:
        f["entry/data/x"].resize(4, axis=0)
        st = f["entry/status"]
        st[()] = np.bytes_(status.encode().ljust(st.dtype.itemsize, b" "))


def test_a_failed_run_whose_last_record_could_not_be_trimmed_is_sound(sound, tmp_path):
    """A full disk: the stop records status 'failed' but cannot shrink the rows of the record it
    was writing. Readers read records_complete rows only, so the file is sound, noted."""
    p = _copy(sound, tmp_path)
    _extra_row(p, "failed")
    fc = check_file(p)
    assert fc.ok and fc.status == "failed" and fc.records_valid == 3, fc
    assert any("unfinished record beyond records_complete = 3" in n for n in fc.notes)
    np.testing.assert_array_equal(read_run(p).codes["x"], read_run(sound / "run.h5").codes["x"])


def test_a_complete_run_with_more_rows_than_records_is_invalid(sound, tmp_path):
    p = _copy(sound, tmp_path)
    _extra_row(p, "complete")
    fc = check_file(p)
    assert not fc.ok and fc.status == "invalid"
    assert "entry/data/x holds 4 rows but records_complete = 3" in fc.problems


def test_a_plan_or_calibration_that_disagrees_with_the_file_is_invalid(sound, tmp_path):
    p = _copy(sound, tmp_path)
    with h5py.File(p, "r+") as f:
        f["entry/records_planned"][()] = 4
        f["entry/data/a"].attrs["units_per_volt"] = 3.0
    fc = check_file(p)
    assert not fc.ok and fc.status == "invalid"
    assert "status complete but 3 of 4 records written" in fc.problems
    assert "the stored scene plans 3 records, records_planned = 4" in fc.problems
    assert any(q.startswith("channel a: volts_per_unit") for q in fc.problems)


def test_format_1_0_files_are_still_read(sound, tmp_path):
    p = _copy(sound, tmp_path)
    with h5py.File(p, "r+") as f:  # what format 1.0 looked like: sos an attribute
        aa = f["entry/instrument/antialias"]
        sos = aa["sos"][()]
        for k in ("sos", "section", "coefficient"):
            del aa[k]
        aa.attrs["sos"] = sos
        f.attrs["file_format_version"] = f["entry"].attrs["file_format_version"] = "1.0"
    fc = check_file(p)
    assert fc.ok and fc.format_version == "1.0" and fc.records_valid == 3
    np.testing.assert_array_equal(read_run(p).header.antialias.sos,
                                  read_run(sound / "run.h5").header.antialias.sos)


#: module names the model info of format 1.0 and 1.1 files wrote, gone since 1.2
OLD_MODULE_NAMES = ("rig.integrators", "rig.lifted", "rig.response.", "(rig.coupled)",
                    "rig/coupled.py")


def test_format_1_1_files_with_the_old_module_names_are_still_read(sound, tmp_path):
    p = _copy(sound, tmp_path)
    with h5py.File(p, "r+") as f:  # 1.1: 1.2's layout, the model info naming old modules
        m = f["entry/model"]
        info = json.loads(m.attrs["model_info_json"])
        assert not [n for n in OLD_MODULE_NAMES if n in m.attrs["model_info_json"]]
        info["method"] = ("exact discretisation ...; lifted (rig.lifted): one exact step Phi^q "
                          "per output sample, q = the decimation")
        m.attrs["model_info_json"] = json.dumps(info)
        f.attrs["file_format_version"] = f["entry"].attrs["file_format_version"] = "1.1"
    fc = check_file(p)
    assert fc.ok and fc.format_version == "1.1" and fc.records_valid == 3
    got = read_run(p).header.model_info
    assert got.method == info["method"] and got.to_dict() == info


def test_other_files_are_results_and_only_a_missing_path_raises(sound, tmp_path):
    text = tmp_path / "notes.h5"
    text.write_bytes(b"\x00\x01 not hdf5 \xff" * 10)
    fc = check_file(text)
    assert isinstance(fc, FileCheck) and not fc.ok and (fc.kind, fc.status) == ("unknown",
                                                                                "not hdf5")
    assert fc.to_dict()["problems"] == ["not an HDF5 file (130 bytes, no HDF5 signature)"]
    with pytest.raises(MissingFile, match="does not exist"):
        check_file(tmp_path / "missing.h5")
    res = daq("check", tmp_path / "missing.h5", cwd=tmp_path)
    assert res.returncode == 2 and "does not exist" in res.stderr and "Traceback" not in res.stderr
    res = daq("check", sound / "run.h5", text, cwd=tmp_path)
    assert res.returncode == 1 and res.stdout.splitlines()[0].endswith("format 1.2")


def test_damage_anywhere_is_never_reported_sound_with_wrong_data(sound, tmp_path):
    """Bytes flipped at 40 random places (fixed seed) and cuts at 20: check_file always returns;
    whenever it calls a file sound, every record reads back equal to the original."""
    src = (sound / "run.h5").read_bytes()
    whole = read_run(sound / "run.h5")
    rng = np.random.default_rng(9)
    p = tmp_path / "damaged.h5"
    bad = 0
    for i, at in enumerate(rng.integers(0, len(src), 60)):
        data = bytearray(src)
        if i < 40:
            data[at] ^= 1 << int(rng.integers(8))
        else:
            data = data[:at]
        p.write_bytes(bytes(data))
        t = time.perf_counter()
        fc = check_file(p)
        assert time.perf_counter() - t < 5.0
        if fc.ok:
            got = read_run(p)
            for c in ("a", "x", "y"):
                np.testing.assert_array_equal(got.codes[c], whole.codes[c])
        else:
            bad += 1
    assert bad >= 20  # every cut at least
    record_inputs("damaged run files (40 bit flips, 20 cuts)", 60)
    record_fault("a bit flipped or the file cut at 60 random places", records_lost=0,
                 outcome="never sound with wrong data; named truncated/corrupt/unreadable")
