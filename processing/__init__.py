"""The analyzer: averaged spectra, frequency responses, coherence, Bode plots."""

from processing.frf import (ESTIMATORS, FrequencyResponse, estimate_frf, expected_h1,
                            frequency_response, random_error)
from processing.spectra import (AVERAGING, WINDOWS, ChannelDataError, ProcessingError,
                                SegmentFFTs, SettingsError, SpectralSettings, Spectrum, WindowInfo,
                                auto_spectrum, coherence, cross_spectrum, estimate_auto_spectra,
                                segment_ffts)

__all__ = [
    "AVERAGING", "ESTIMATORS", "WINDOWS", "ChannelDataError", "FrequencyResponse",
    "ProcessingError", "SegmentFFTs", "SettingsError", "SpectralSettings", "Spectrum",
    "WindowInfo", "auto_spectrum", "coherence", "cross_spectrum", "estimate_auto_spectra",
    "estimate_frf", "expected_h1", "frequency_response", "random_error", "segment_ffts",
]
