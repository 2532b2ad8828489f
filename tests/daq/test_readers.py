"""Every file the project writes (run, spectra, trajectory, a dataset's run files and manifest) opens completely -- every object,
every attribute -- in other readers: HDF5 1.10's command-line tools, an older h5py (HDF5 1.14),
xarray under the h5netcdf and netCDF4 engines, nexusformat. The files are written by the real
CLI in subprocesses; ``python3 tasks.py test`` makes ``.venv-compat`` (the older h5py), ``python3
tasks.py setup-system`` installs the HDF5 tools (as root, with apt-get; CI runs it), and a test
whose reader is missing skips saying why."""

import hashlib
import json
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest

from faults import record_readers

ROOT = Path(__file__).resolve().parents[2]
COMPAT_PY = ROOT / ".venv-compat" / "bin" / "python"
SHORT = ["--scene", "ishizaki2009", "--records", "2", "--duration", "5", "--rate", "100",
         "--set", "acquisition.settle_s=5"]


def daq(*args, cwd, check=True):
    """The real CLI in a subprocess (SIGINT restored, as in an interactive shell)."""
    res = subprocess.run([sys.executable, "-m", "daq.cli", *map(str, args)], cwd=cwd,
                         capture_output=True, text=True, timeout=300,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    if check:
        assert res.returncode == 0, res.stderr
    return res


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("readers")
    daq("acquire", *SHORT, "--seed", "5", "--out", "run.h5", "-q", cwd=d)
    daq("analyze", "run.h5", "--spectra", "spectra.h5", cwd=d)
    daq("simulate", "double-rod", "--duration", "2", "--method", "rk4", "--dt", "0.01",
        "--output-dt", "0.1", "--out", "trajectory.h5", cwd=d)
    (d / "sweep.toml").write_text(
        'seed = 5\nscene = "ishizaki2009"\nset = ["acquisition.records=2", '
        '"acquisition.record_s=5", "acquisition.settle_s=5"]\n'
        '[grid]\n"source.level_vrms" = [0.05, 0.1]\n[analysis]\nnperseg = 500\n')
    daq("dataset", "sweep.toml", "--out", "ds", "--workers", "1", cwd=d)
    daq("sine", "ishizaki2009", "--fmin", "1", "--fmax", "2", "--points", "2",
        "--keep-records", "--random-error", "0", "--out", "sine.h5", "-q", cwd=d)
    daq("sine", "ishizaki2009", "--mode", "swept", "--fmin", "1", "--fmax", "1.2", "--points",
        "3", "--sweep-tolerance", "0.05", "--keep-records", "--out", "swept.h5", "-q", cwd=d)
    out = {k: d / f"{k}.h5" for k in ("run", "spectra", "trajectory", "sine", "swept")}
    out["dataset run"] = d / "ds" / "runs" / "run_000000.h5"
    out["dataset manifest"] = d / "ds" / "manifest.h5"
    return out


def _objects(path: Path) -> tuple[list[str], int]:
    """Every group and dataset path and the number of attributes, as h5py (HDF5 2.0) sees them."""
    names, n_attrs = ["/"], len(h5py.File(path, "r").attrs)
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            nonlocal n_attrs
            names.append("/" + name)
            n_attrs += len(obj.attrs)
        f.visititems(visit)
    return names, n_attrs


def test_files_use_the_hdf5_1_10_format_bounds_and_checksum_every_chunked_dataset(files):
    for kind, path in files.items():
        assert path.read_bytes()[8] == 3, f"{kind}: superblock v3 (libver v110)"
        with h5py.File(path, "r") as f:
            chunked = []
            f.visititems(lambda n, o: chunked.append(o) if isinstance(o, h5py.Dataset)
                         and o.chunks is not None else None)
            # the manifest's arrays are virtual (no chunks of its own: its sources are checked)
            assert chunked or kind == "dataset manifest", kind
            assert all(ds.fletcher32 for ds in chunked), kind


@pytest.mark.skipif(shutil.which("h5dump") is None,
                    reason="h5dump (Debian hdf5-tools) not installed: `python3 tasks.py "
                           "setup-system` installs it (as root, with apt-get)")
def test_hdf5_1_10_tools_dump_every_object_of_every_file(files):
    version = subprocess.run(["h5dump", "-V"], capture_output=True, text=True).stdout
    for kind, path in files.items():
        res = subprocess.run(["h5dump", str(path)], capture_output=True, text=True, timeout=120)
        assert res.returncode == 0 and res.stderr == "", f"{kind}: {res.stderr[:500]}"
        names, n_attrs = _objects(path)
        for name in names[1:]:  # every object appears in the dump
            assert f'"{name.rsplit("/", 1)[-1]}"' in res.stdout, (kind, name)
        if kind == "dataset manifest":  # h5dump follows its external links into the runs
            assert res.stdout.count("ATTRIBUTE \"") > n_attrs, kind
        else:
            assert res.stdout.count("ATTRIBUTE \"") == n_attrs, kind
    record_readers("h5dump " + version.split()[-1].strip())


@pytest.mark.skipif(not COMPAT_PY.exists(),
                    reason=".venv-compat (h5py 3.11, HDF5 1.14) not installed: `python3 tasks.py "
                           "test` creates it")
def test_an_older_h5py_reads_every_object_and_attribute(files):
    script = textwrap.dedent("""
        import hashlib, json, sys, h5py, numpy
        out = {"hdf5": h5py.version.hdf5_version, "h5py": h5py.version.version, "files": {}}
        for path in sys.argv[1:]:
            seen, n_attrs, values = ["/"], 0, {}
            with h5py.File(path, "r") as f:
                n_attrs += len(f.attrs); [f.attrs[k] for k in f.attrs]
                def visit(name, obj):
                    global n_attrs
                    seen.append("/" + name)
                    n_attrs += len(obj.attrs)
                    for k in obj.attrs:
                        obj.attrs[k]
                    if isinstance(obj, h5py.Dataset):
                        v = obj[()]
                        if obj.dtype.kind in "iuf":
                            values["/" + name] = hashlib.sha256(
                                numpy.ascontiguousarray(v).tobytes()).hexdigest()
                f.visititems(visit)
            out["files"][path] = {"names": seen, "n_attrs": n_attrs, "sums": values}
        print(json.dumps(out))
    """)
    res = subprocess.run([str(COMPAT_PY), "-c", script, *map(str, files.values())],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    got = json.loads(res.stdout)
    assert got["hdf5"].startswith("1.14"), got["hdf5"]
    for kind, path in files.items():
        names, n_attrs = _objects(path)
        mine = got["files"][str(path)]
        assert sorted(mine["names"]) == sorted(names) and mine["n_attrs"] == n_attrs, kind
        with h5py.File(path, "r") as f:  # the same bytes as HDF5 2.0 reads
            assert mine["sums"], kind
            for name, digest in mine["sums"].items():
                assert digest == hashlib.sha256(
                    np.ascontiguousarray(f[name][()]).tobytes()).hexdigest(), (kind, name)
    record_readers(f"h5py {got['h5py']} (HDF5 {got['hdf5']})")


def _groups(path: Path) -> list[str]:
    with h5py.File(path, "r") as f:
        out = ["/"]
        f.visititems(lambda n, o: out.append(n) if isinstance(o, h5py.Group) else None)
    return out


@pytest.mark.parametrize("engine", ["h5netcdf", "netcdf4"])
def test_xarray_opens_every_group_of_every_file(files, engine):
    import xarray as xr

    pytest.importorskip({"netcdf4": "netCDF4"}.get(engine, engine))
    for kind, path in files.items():
        for g in _groups(path):
            with xr.open_dataset(path, group=None if g == "/" else g, engine=engine) as ds:
                ds.load()
    with xr.open_dataset(files["run"], group="entry/data", engine=engine) as ds:
        with h5py.File(files["run"], "r") as f:  # CF packing decodes the codes to volts
            a = f["entry/data/a"]
            np.testing.assert_array_equal(ds["a"].values,
                                          a[()] * a.attrs["scale_factor"] + a.attrs["add_offset"])
    with xr.open_dataset(files["run"], group="entry/instrument/antialias", engine=engine) as ds:
        assert ds["sos"].dims == ("section", "coefficient") and ds["sos"].shape[1] == 6
        np.testing.assert_array_equal(ds["sos"].values[:, 3], 1.0)  # a0 of every section
    record_readers(f"xarray {xr.__version__} ({engine})")


def test_nexusformat_loads_every_file_and_finds_the_default_plot(files):
    nexus = pytest.importorskip("nexusformat.nexus")
    import nexusformat

    for kind, path in files.items():
        root = nexus.nxload(str(path), "r")
        try:
            if kind == "dataset manifest":
                # nexusformat 2.1 loads it, but its tree printer recurses without end on an
                # external link to a group ("Cannot link to another NXlink object"): walk the
                # stacked arrays instead, and read one through the library
                names = [n for n in _objects(path)[0][1:] if "/" not in n[1:]]
                assert all(n[1:] in root for n in names), kind
                assert root["a"].nxdata.shape[0] == 2, kind
                continue
            assert len(root.tree.splitlines()) >= len(_objects(path)[0]) - 1, kind
        finally:
            root.close()
    root = nexus.nxload(str(files["run"]), "r")
    try:  # the NeXus default chain leads to the raw stage-acceleration channel
        data = root.plottable_data
        assert data.nxsignal.nxname == "a" and data.nxsignal.shape == (2, 500)
        assert [ax.nxname for ax in data.nxaxes] == ["record", "time"]
    finally:
        root.close()
    record_readers(f"nexusformat {nexusformat.__version__}")
