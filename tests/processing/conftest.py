"""Fixtures shared by the processing tests: ``visa``, a reset pyvisa-py session to the test
module's own ``server`` fixture (tests/virtual_analyzer.py)."""

from virtual_analyzer import visa  # noqa: F401  (a fixture, found by name)
