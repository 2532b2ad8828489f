"""Records -> spectra, frequency responses, fits, comparisons, reports and pictures.

A notebook writes ``processing.analyze(daq.read_run(path))``. The names below are imported on
first use (PEP 562), so ``import processing`` costs nothing and ``daq analyze`` loads only the
modules it needs. Where each lives: spectra and windows :mod:`processing.spectra`; H1/H2/Hv
:mod:`processing.frf`; E[H1] :mod:`processing.leakage`; measured against the model
:mod:`processing.compare`; modal fits :mod:`processing.modal`; the analyzer's recipe
:mod:`processing.analyzer`; its text :mod:`processing.report`; its files
:mod:`processing.writers`; figures :mod:`processing.plots` and :mod:`processing.views`.
"""

from __future__ import annotations

from rig.lazy_exports import lazy_exports

_EXPORTS = {
    "processing.spectra": ("AVERAGING", "WINDOWS", "ProcessingError", "SettingsError",
                           "ChannelDataError", "SpectralSettings", "WindowInfo", "SegmentFFTs",
                           "segment_ffts", "Spectrum", "auto_spectrum", "cross_spectrum",
                           "coherence", "estimate_auto_spectra", "window_autocorrelation"),
    "processing.frf": ("ESTIMATORS", "MeasuredResponse", "estimate_frf", "frequency_response",
                       "random_error"),
    "processing.leakage": ("expected_h1", "expected_h1_taps", "expected_estimate",
                           "ExpectedEstimate"),
    "processing.compare": ("compare", "Comparison", "BandStats", "PeakBias", "ModelError"),
    "processing.modal": ("fit_modes", "ModalFit", "Mode", "FitError"),
    "processing.modal_model": ("InputSpectrum",),
    "processing.rotation": ("rotation_reading", "RotationReading"),
    "processing.analyzer": ("analyze", "Analysis", "AnalyzerSettings", "model_at_lines"),
    "processing.report": ("report_markdown",),
    "processing.writers": ("write_csv", "write_report", "write_spectra", "write_bode_png"),
    "processing.plots": ("bode_figure", "measured_bode_figure", "nyquist_figure",
                         "coherence_figure"),
    "processing.views": ("bode_figures", "write_views"),
}
_WHERE = {name: (module, name) for module, names in _EXPORTS.items() for name in names}

__all__ = sorted(_WHERE)

__getattr__, __dir__ = lazy_exports("processing", _WHERE, globals())
