"""The analyzer's option values, importable without numpy (the command line offers them as
choices before any analysis runs): FFT windows, averaging modes, FRF estimators."""

#: FFT windows (:class:`processing.spectra.SpectralSettings` ``window``)
WINDOWS = ("uniform", "hann", "flattop", "force", "exponential")
#: averaging of the spectra (:class:`processing.spectra.SpectralSettings`); peak hold has no
#: cross spectra
AVERAGING = ("rms", "vector", "exponential", "peak")
#: FRF estimators (:func:`processing.frf.frequency_response`)
ESTIMATORS = ("h1", "h2", "hv")
