"""processing's public names: re-exported lazily (PEP 562), so ``import processing`` imports
nothing heavy, and each name is the object of the module that defines it."""

import subprocess
import sys

import pytest

import processing


def test_import_processing_loads_no_submodule_and_no_numpy():
    code = ("import sys, processing\n"
            "loaded = sorted(m for m in sys.modules if m.startswith('processing.') or m in "
            "('numpy', 'matplotlib', 'h5py', 'scipy'))\n"
            "print(loaded)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_every_public_name_resolves_to_its_defining_module():
    import processing.analyzer
    import processing.frf

    assert processing.analyze is processing.analyzer.analyze
    assert processing.MeasuredResponse is processing.frf.MeasuredResponse
    for name in processing.__all__:
        obj = getattr(processing, name)
        assert obj is not None, name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        processing.nope  # noqa: B018
