"""The analysis outputs as an HDF5 group: one writer for the spectra file and the sweep's run files.

:func:`write_analysis_group` writes the variables of an :class:`processing.analyzer.Analysis`
over the analyzer's lines into a group, laid out as netCDF-4 would be (a ``frequency``
dimension scale [Hz]; complex quantities as ``_real``/``_imag`` pairs, netCDF having no complex
type; every variable with ``units`` and ``long_name``). Two files hold such a group:
:func:`processing.writers.write_spectra` (its own file, group ``spectra``) and
:func:`processing.dataset.runfile.write_outputs` (a sweep's run file, ``entry/analysis``); the
group's attributes are theirs. ``keep`` selects parts (all by default):

- ``spectra``: G_aa, G_xx, G_yy [(unit)^2/Hz]; G_ax, G_ay (complex) [(m/s^2)(unit)/Hz];
- ``frf``: H_t [m/(m/s^2)], Theta_2 [rad/(m/s^2)] (complex, H1 or H2), coherence_x,
  coherence_y [1] and their Bendat-Piersol errors ``<name>_relative_error`` [1];
- ``expected``: the exact whole-chain ``model_<name>`` and, if computed, E[H1] as
  ``expected_<name>`` (complex).

The variables are written response by response (H_t's, then Theta_2's). The two files differ
where their formats fixed it before they shared this writer (``run_file=True``): the run file's
variables carry no fletcher32 checksum and no expected coherence, and two long names are worded
more briefly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["write_analysis_group", "KEEP_ALL"]

#: The parts of the group (module docstring), all kept.
KEEP_ALL = {"spectra": True, "frf": True, "expected": True}


def write_analysis_group(g, analysis, keep: dict | None = None, *, run_file: bool = False):
    """Write the kept variables of ``analysis`` (module docstring) into the h5py group ``g``;
    returns the ``frequency`` scale. ``keep``: {part: bool}, a missing part is kept."""
    a = analysis
    keep = {**KEEP_ALL, **{k: bool(v) for k, v in (keep or {}).items() if k in KEEP_ALL}}
    checksum = {} if run_file else {"fletcher32": True}
    f = a.freqs_hz
    fr = g.create_dataset("frequency", data=f, track_times=False)
    fr.make_scale("frequency")
    fr.attrs["units"] = "Hz"
    fr.attrs["long_name"] = "frequency (the analyzer's lines)"

    def variable(name, data, *, units, long_name):
        ds = g.create_dataset(name, data=np.asarray(data, dtype=float), track_times=False,
                              **checksum)
        ds.dims[0].attach_scale(fr)
        ds.attrs["units"] = units
        ds.attrs["long_name"] = long_name

    def complex_variable(name, data, *, units, long_name):
        data = np.asarray(data, dtype=complex)
        for part, arr in (("real", data.real), ("imag", data.imag)):
            variable(f"{name}_{part}", arr, units=units, long_name=f"{part} part of {long_name}")

    if keep["spectra"]:
        for c, name in (("a", "G_aa"), ("x", "G_xx"), ("y", "G_yy")):
            s = a.spectra[c]
            variable(name, s.values, units=s.value_units,
                     long_name=f"one-sided auto spectral density of {c}")
        for c, name in (("ax", "G_ax"), ("ay", "G_ay")):
            s = a.spectra[c]
            complex_variable(name, s.values, units=s.value_units,
                             long_name=f"one-sided cross spectral density <conj(A) "
                                       f"{c[1].upper()}>")
    budget = a.coherence_budget
    for frf, name, c, what in ((a.h_t, "H_t", "x", "mirror translation"),
                               (a.theta_2, "Theta_2", "y", "mirror rotation")):
        unit = f"{a.spectra[c].units[0]}/({a.spectra['a'].units[0]})"
        if keep["frf"]:
            est = frf.estimator.upper()
            complex_variable(name, frf.h, units=unit, long_name=(
                f"measured {name} = G_a{c} / G_aa ({est})" if run_file else
                f"{name} = G_a{c} / G_aa, measured {what} per unit stage acceleration ({est})"))
            variable(f"coherence_{c}", frf.coherence, units="1",
                     long_name=f"magnitude-squared coherence of a and {c}")
            if not run_file and budget is not None and np.array_equal(budget.freqs_hz, f):
                variable(f"expected_coherence_{c}", budget.expected[c], units="1",
                         long_name=f"expected coherence of a and {c} (optical lever geometry, "
                                   "noise floors, quantisation, leakage: "
                                   "processing.coherence_model)")
            variable(f"{name}_relative_error", frf.relative_error, units="1",
                     long_name=f"Bendat-Piersol normalised random error of |{name}| (1 sigma; "
                               "also the phase's std in rad)")
        if keep["expected"]:
            complex_variable(f"model_{name}", getattr(a.model, name.lower()), units=unit,
                             long_name=f"exact {name} of the whole sampled chain"
                                       + (" at the lines" if run_file else ""))
            if a.expected is not None:
                complex_variable(f"expected_{name}", getattr(a.expected, name.lower()),
                                 units=unit, long_name=f"expected estimate E[H1] of {name} "
                                                       "(leakage bias included)")
    return fr
