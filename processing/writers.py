"""The files of an analysis: CSV of the responses, Bode PNG, Markdown report, HDF5 spectra.

:func:`write_csv` writes the measured H_t (x) and Theta_2 (y) over the display band
(:data:`CSV_COLUMNS`, full float precision), :func:`write_bode_png` both Bode diagrams side by
side, :func:`write_report` the Markdown report (:func:`processing.report.analysis_report`).
Every file is written under a temporary name and renamed when complete; an existing file is
replaced only with ``force``.

:func:`write_spectra` writes an :class:`processing.analyzer.Analysis` into its own file (never into
the run file), one group (:data:`GROUP`, ``"spectra"``) laid out as netCDF-4 would be, so
``xarray.open_dataset(path, group="spectra", engine="h5netcdf")`` returns labelled arrays::

    /                        @file_format = "pendulum-daq spectra" @file_format_version
                             @creator @source_run @scene @seed @status @records
                             @records_planned
    spectra/                 @title @<analyzer settings> (settings_<name>) @<spectral settings>
                             (fs_hz, nperseg, noverlap, window, averaging, detrend,
                             resolution_hz, enbw_hz, n_averages, n_effective) @model_source
      frequency (frequency,) [Hz] dimension scale: the analyzer's lines, 0 .. span
      G_aa, G_xx, G_yy       one-sided auto PSDs [(unit)^2/Hz] of a, x, y
      G_ax_real, G_ax_imag   one-sided cross PSD <conj(A) X> [(m/s^2)(m)/Hz]; G_ay_* likewise
      H_t_real, H_t_imag     measured H_t = G_ax / G_aa [m/(m/s^2)]
      Theta_2_real, _imag    measured Theta_2 = G_ay / G_aa [rad/(m/s^2)]
      coherence_x, coherence_y   gamma^2 of (a, x) and (a, y) [1]
      expected_coherence_x, _y   their expected values (processing.coherence_model), with E[H1]
      H_t_relative_error, Theta_2_relative_error   Bendat-Piersol eps [1] (1 sigma of |H|/|H|
                             and of the phase in rad)
      model_H_t_*, model_Theta_2_*   exact whole-chain response at the lines (_real, _imag)
      expected_H_t_*, expected_Theta_2_*   E[H1] at the lines (only if computed)

Complex quantities are pairs of ``_real``/``_imag`` variables (netCDF has no complex type); NaN
marks undefined lines (0 Hz after the detrend). The file is written under a temporary name and
renamed when complete; an existing file is replaced only with ``force``. HDF5 1.10 format bounds
(readable by HDF5 1.10 to 2.0); every variable carries a fletcher32 checksum.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from daq.hdf5 import LIBVER, attr_value
from processing.analysis_group import write_analysis_group
from rig.output_files import atomic_output, write_columns_csv

__all__ = ["GROUP", "FORMAT", "FORMAT_VERSION", "CSV_COLUMNS", "write_spectra", "write_csv",
           "write_bode_png", "write_report"]

#: The CSV columns (SPEC section 5): x in m per m/s^2, y in rad per m/s^2, gain in dB re 1 unit,
#: phase in degrees wrapped to (-180, 180], coherence gamma^2 in [0, 1].
CSV_COLUMNS = ("frequency_hz", "x_re", "x_im", "x_gain_db", "x_phase_deg", "x_coherence",
               "y_re", "y_im", "y_gain_db", "y_phase_deg", "y_coherence")

GROUP = "spectra"
FORMAT = "pendulum-daq spectra"
#: 1.1: HDF5 1.10 format bounds (daq.hdf5.LIBVER), a fletcher32 checksum on every variable.
FORMAT_VERSION = "1.1"


def _attr(value):
    """A value netCDF readers understand (:func:`daq.hdf5.attr_value`, numeric lists as
    float)."""
    return attr_value(value, list_dtype=float)


def write_spectra(analysis, path, *, force: bool = False, group: str = GROUP) -> Path:
    """Write the spectra, responses, coherences, model and E[H1] of ``analysis`` (module
    docstring) into a new HDF5 file ``path``.

    Parameters
    ----------
    analysis : processing.analyzer.Analysis
    path : output file (refused if it exists, unless ``force``).
    force : replace an existing file (only once the new one is complete).
    group : name of the group (default :data:`GROUP`).

    Returns
    -------
    Path : ``path``.
    """
    from rig.output_files import software_version

    a = analysis
    path = Path(path)
    sp = a.spectral
    with atomic_output(path, force=force) as tmp:
        with h5py.File(tmp, "w", track_order=True, libver=LIBVER) as fh:
            run = a.run
            for k, v in {"file_format": FORMAT, "file_format_version": FORMAT_VERSION,
                         "creator": f"pendulum-daq {software_version()}",
                         "source_run": run.source, "scene": run.scene, "seed": np.int64(run.seed),
                         "status": run.status, "records": np.int64(run.records),
                         "records_planned": np.int64(run.records_planned)}.items():
                fh.attrs[k] = _attr(v)
            g = fh.create_group(group, track_order=True)
            g.attrs["title"] = (f"{run.scene}, seed {run.seed}: averaged spectra and frequency "
                                f"responses of {run.records} records ({sp.window} window, "
                                f"{sp.nperseg} samples per FFT)")
            for k, v in a.settings.describe().items():
                g.attrs[f"settings_{k}"] = _attr(v)
            for k, v in {"fs_hz": sp.fs, "nperseg": sp.nperseg, "noverlap": sp.noverlap,
                         "window": sp.window, "averaging": sp.averaging,
                         "detrend": sp.detrend, "resolution_hz": sp.resolution_hz,
                         "enbw_hz": sp.window_info.enbw_hz, "n_averages": a.h_t.n_averages,
                         "n_effective": a.h_t.n_effective, "estimator": a.h_t.estimator,
                         "model_source": a.model.source,
                         "model_note": "exact whole sampled chain (rig.bench.expected_response "
                                       "sampled=True): accelerometer high-pass included"}.items():
                g.attrs[k] = _attr(v)
            if a.expected is not None:
                g.attrs["expected_n_fft"] = np.int64(a.expected.n_fft)
                g.attrs["expected_alias_bound"] = a.expected.alias_bound
            write_analysis_group(g, a)
    return path


def write_bode_png(a, path, *, force: bool = False, dpi: int = 100,
                   phase: str = "wrapped") -> Path:
    """Both Bode diagrams side by side in one PNG (translation left, rotation right): the
    ``bode`` view of :func:`processing.views.write_views`."""
    from processing.views import write_views

    return write_views(a, path, "bode", phase=phase, force=force, dpi=dpi)[0]


def write_csv(a, path, *, force: bool = False) -> Path:
    """The measured H_t (x) and Theta_2 (y) over the display band as CSV (:data:`CSV_COLUMNS`;
    x in m per m/s^2, y in rad per m/s^2, SPEC section 5); full float precision."""
    path = Path(path)
    m = a.display
    cols = [a.freqs_hz[m]]
    for frf in (a.h_t, a.theta_2):
        cols += [frf.h.real[m], frf.h.imag[m], frf.magnitude_db[m], frf.phase_deg[m],
                 frf.coherence[m]]
    return write_columns_csv(path, CSV_COLUMNS, cols, force=force)


def write_report(a, path, *, force: bool = False) -> Path:
    """The Markdown report (:meth:`processing.analyzer.Analysis.report`)."""
    path = Path(path)
    text = a.report()
    with atomic_output(path, force=force) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path
