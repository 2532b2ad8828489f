"""Fixtures shared by the solver tests: the paper's chain and 100 s of its drive with the
fixed-step DOP853 reference on it."""

import pytest

from benchmarks.work_precision import paper_input
from rig.scene import load_scene

from chains import dop853_fixed


@pytest.fixture(scope="module")
def paper():
    return load_scene("ishizaki2009").chain


@pytest.fixture(scope="module")
def piece(paper):
    """100 s of the paper's drive and fixed-step DOP853 at 2 steps per sample on it (every
    0.01 s; within 1e-12 of 4 steps per sample, tests/rig/solvers/test_exponential.py)."""
    base = paper_input(100.0)
    return base, dop853_fixed(paper, base, out_every=10)
