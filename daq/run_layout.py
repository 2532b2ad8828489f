"""Where a run file keeps what: the HDF5 paths of its groups and datasets, declared once.

Every reader and writer of a run file (:mod:`daq.hdf5`, :mod:`daq.check`, the sweep's
:mod:`processing.dataset`) names the file's objects through these constants, so the layout
drawn in docs/run-file.md changes in one place. Paths are relative to the file's root (h5py
takes them on the file object: ``f[TRUTH]``, ``TRUTH in f``); :func:`member` joins a group and
the names below it (``member(DATA, "record")`` is ``"entry/data/record"``).

The groups a sweep adds to its run files (:func:`processing.dataset.runfile.write_outputs`) are
declared here too (:data:`DATASET`, :data:`ANALYSIS`): a run file has one layout, whoever adds
to it.
"""

from __future__ import annotations

__all__ = ["ENTRY", "STATUS", "MESSAGE", "RECORDS_COMPLETE", "RECORDS_PLANNED", "DATA",
           "CLIPPING", "SATURATION", "TRUTH", "MODEL", "INSTRUMENT", "ACQUISITION", "ANTIALIAS",
           "SCENE", "SCENE_SETTINGS", "DATASET", "ANALYSIS", "RECORD", "TIME", "FREQUENCY",
           "COUNT", "BODY", "RECORD_START", "MODAL", "member", "name_of"]


def member(group: str, *names: str) -> str:
    """The path of ``names`` below ``group`` (``"/"``-joined)."""
    return "/".join((group, *names))


#: The NXentry every other object lives in (a sweep's manifest links to it).
ENTRY = "entry"
#: Scalars of the run's progress: status text, why it stopped, records written and planned.
STATUS, MESSAGE = member(ENTRY, "status"), member(ENTRY, "message")
RECORDS_COMPLETE, RECORDS_PLANNED = (member(ENTRY, "records_complete"),
                                     member(ENTRY, "records_planned"))
#: The ADC codes (NXdata: one dataset per channel, rows = records).
DATA = member(ENTRY, "data")
#: Per-sample flags and per-record counts: ADC clipping, sensor saturation.
CLIPPING, SATURATION = member(ENTRY, "clipping"), member(ENTRY, "saturation")
#: The ground truth at the channels' instants (absent if the scene keeps none).
TRUTH = member(ENTRY, "truth")
#: The exact model response on the record's FFT grid and the model's description.
MODEL = member(ENTRY, "model")
#: The instrument: the acquisition plan and the anti-alias filter.
INSTRUMENT = member(ENTRY, "instrument")
ACQUISITION, ANTIALIAS = member(INSTRUMENT, "acquisition"), member(INSTRUMENT, "antialias")
#: The resolved scene (its settings as JSON).
SCENE = member(ENTRY, "scene")
SCENE_SETTINGS = member(SCENE, "settings_json")
#: Added by a sweep: the run's place in the sweep, and the analysis outputs it keeps.
DATASET, ANALYSIS = member(ENTRY, "dataset"), member(ENTRY, "analysis")

#: Names that recur below the groups: the record and time scales (DATA, TRUTH, CLIPPING,
#: SATURATION), the frequency scale (MODEL, ANALYSIS), the per-record counts (CLIPPING,
#: SATURATION), the body scale (TRUTH), each record's start time (DATA, TRUTH) and the modal
#: fits (ANALYSIS).
RECORD, TIME, FREQUENCY, COUNT, BODY = "record", "time", "frequency", "count", "body"
RECORD_START, MODAL = "record_start", "modal"


def name_of(path: str) -> str:
    """The last name of ``path`` (what its parent group calls it: ``name_of(DATA)`` is
    ``"data"``)."""
    return path.rsplit("/", 1)[-1]
