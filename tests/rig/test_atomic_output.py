"""The one atomic-write helper, ``rig.output_files.atomic_output``: a file appears whole or not at
all, another writer's file is never overwritten without ``force`` (even one that appears while
this one writes), a writer that creates its own file gets a free name, and nothing temporary
stays behind. Files are read back with h5py and plain reads."""

import h5py
import numpy as np
import pytest

from rig.errors import ForceRequired
from rig.output_files import atomic_output


def _leftovers(d, name):
    return sorted(p.name for p in d.iterdir() if p.name.startswith(f".{name}."))


def test_a_file_published_meanwhile_by_another_writer_is_kept_and_ours_discarded(tmp_path):
    out = tmp_path / "table.csv"
    with pytest.raises(ForceRequired, match="table.csv' exists"):
        with atomic_output(out, force=False) as tmp:
            tmp.write_text("ours\n")
            out.write_text("theirs\n")  # another process finishes first
    assert out.read_text() == "theirs\n"
    assert _leftovers(tmp_path, "table.csv") == []
    with atomic_output(out, force=True, durable=True) as tmp:  # with force: ours replaces it
        tmp.write_text("ours\n")
    assert out.read_text() == "ours\n"
    assert _leftovers(tmp_path, "table.csv") == []


def test_an_unreserved_name_lets_a_writer_that_refuses_existing_files_create_its_own(tmp_path):
    out = tmp_path / "run.h5"
    with atomic_output(out, force=False, suffix=".partial.h5", reserve=False) as tmp:
        assert not tmp.exists() and tmp.parent == tmp_path
        assert tmp.name.startswith(".run.h5.") and tmp.name.endswith(".partial.h5")
        with h5py.File(tmp, "x") as f:  # "x": fails if the file exists
            f["v"] = np.arange(3)
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f["v"][()], [0, 1, 2])
    assert _leftovers(tmp_path, "run.h5") == []


def test_a_writer_that_fails_leaves_neither_the_file_nor_a_temporary_one(tmp_path):
    out = tmp_path / "plan.json"
    with pytest.raises(ZeroDivisionError):
        with atomic_output(out, force=True, durable=True) as tmp:
            tmp.write_text("{")
            1 / 0
    assert not out.exists() and _leftovers(tmp_path, "plan.json") == []
