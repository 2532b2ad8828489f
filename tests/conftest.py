"""Shared test setup: designed filters are cached in a per-session directory, never in the user's
cache (daq.antialias.design_cache_dir)."""

import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def _design_cache(tmp_path_factory):
    old = os.environ.get("PENDULUM_DAQ_CACHE")
    os.environ["PENDULUM_DAQ_CACHE"] = str(tmp_path_factory.mktemp("design-cache"))
    yield
    if old is None:
        os.environ.pop("PENDULUM_DAQ_CACHE", None)
    else:
        os.environ["PENDULUM_DAQ_CACHE"] = old


def pytest_sessionfinish(session, exitstatus):
    """Write the reliability tests' record (tests/faults.py) for the README's table."""
    from faults import write_report

    write_report()
