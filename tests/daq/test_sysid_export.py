"""A run exported as a system-identification benchmark loads in nonlinear_benchmarks' own types,
and the emulator's noiseless output misses the test data by exactly the predicted noise floor.

The floor is each sensor's white noise through the anti-alias filter plus two quantisations
(daq.sysid.noise_floor_rms). Its estimate from the 20,000 test samples (nearly white noise) has
a relative standard deviation of about 1 / sqrt(2 x 20,000) = 0.5 %: the tolerance, 2.5 %, is 5
of those.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest


@pytest.fixture(scope="module")
def sysid_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("sysid")
    cmd = [sys.executable, "-m", "daq.cli"]
    p = subprocess.run(cmd + ["acquire", "ishizaki2009", "--records", "10", "--seed", "5",
                              "--out", str(d / "run.h5"), "-q"], capture_output=True,
                       text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    p = subprocess.run(cmd + ["export", str(d / "run.h5"), "--sysid", str(d / "sysid.npz")],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    return d / "sysid.npz"


def test_the_export_loads_as_nonlinear_benchmarks_input_output_data(sysid_file):
    nb = pytest.importorskip("nonlinear_benchmarks")
    z = np.load(sysid_file)
    train = nb.Input_output_data(u=z["u_train"], y=z["y_train"],
                                 sampling_time=float(z["sampling_time"]), name="train")
    test = nb.Input_output_data(u=z["u_test"], y=z["y_test"],
                                sampling_time=float(z["sampling_time"]), name="test")
    assert len(train) == 80_000 and len(test) == 20_000  # 8 and 2 whole records
    assert list(z["channels"]) == ["a", "x", "y"] and list(z["units"]) == ["m/s^2", "m", "rad"]
    np.testing.assert_array_equal(np.concatenate([z["u_train"], z["u_test"]]), z["u"])
    assert 0.05 < np.std(z["u"]) < 0.15  # the paper's 0.1 V rms drive


def test_the_oracle_misses_the_test_data_by_the_predicted_noise_floor(sysid_file):
    nb = pytest.importorskip("nonlinear_benchmarks")
    z = np.load(sysid_file)
    cut = z["u_train"].size
    for k, name in enumerate(z["channels"]):
        rmse = nb.error_metrics.RMSE(z["y_test"][:, k], z["y_oracle"][cut:, k])
        assert rmse / z["noise_floor_rms"][k] == pytest.approx(1.0, abs=0.025), name
        # and the signal is far above it: a model's error has room to show
        assert np.std(z["y_test"][:, k]) > 30 * z["noise_floor_rms"][k], name


def test_sysid_options_are_checked_before_anything_is_read(tmp_path):
    run = tmp_path / "missing.h5"
    run.write_bytes(b"")
    p = subprocess.run([sys.executable, "-m", "daq.cli", "export", str(run), "--sysid",
                        str(tmp_path / "s.txt")], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "a system-identification file is a NumPy .npz file" in p.stderr
    assert "Traceback" not in p.stderr
