"""A real small file system for the full-disk tests (imported by test modules: pytest puts this
directory on sys.path): :func:`mounted` mounts a tmpfs of a given size and always unmounts it,
or skips the test where mounting needs a root this machine does not give."""

from __future__ import annotations

import os
import shutil
import subprocess
from contextlib import contextmanager
from pathlib import Path

import pytest


@contextmanager
def mounted(d: Path, size: str, *, why: str = ""):
    """Mount a tmpfs of ``size`` (mount(8) syntax, e.g. ``"6m"``) on the new folder ``d``; yield
    ``d``, then unmount it lazily. Skips (``why`` appended to the reason) without root."""
    d.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("a small tmpfs needs root and mount(8) to test a full disk for real")
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(d)],
                         capture_output=True, text=True)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({res.stderr.strip()}){why}")
    try:
        yield d
    finally:
        subprocess.run(["umount", "-l", str(d)], capture_output=True)
