"""``python -m daq.cli``: the console script."""

from daq.cli import run

run()
