"""A virtual Agilent 35670A: the emulated bench and this project's analysis behind the
instrument's SCPI commands.

This sub-package composes the acquisition (``daq``) and the analysis (``processing``), so it
sits above the rest of ``processing`` as a declared sub-layer (``tests/test_layers.py``): it may
import any of ``daq``, and nothing else in ``processing`` imports it. Its modules:

- :mod:`.scpi`: the SCPI 1999 / IEEE 488.2 engine (parser, command table, error queue),
  independent of the transport;
- :mod:`.blocks`: ASCII and IEEE 488.2 definite-length binary trace data;
- :mod:`.measurement_mode`: what a measurement mode is; :mod:`.measurement`: the modes (FFT:
  ``daq.acquire`` + ``processing.analyze``) and the instrument's span/lines semantics on the
  bench; :mod:`.sine_mode`: the swept sine (``processing.sine_sweep.measure_sine``);
- :mod:`.traces`: trace feeds and formats; :mod:`.status`: the status registers;
- :mod:`.analyzer35670a`: the instrument (state, measurement thread); :mod:`.commands`: its
  command table;
- :mod:`.server`: the raw SCPI socket server (``daq serve --scpi HOST:PORT``).
"""
