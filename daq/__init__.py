"""daq: the acquisition -- the bench's analog truth through the anti-alias filter and ADC into
records, streamed to sinks (a run file, memory, a live view), and the run file read back.

The public names below are imported on first use (PEP 562), so ``import daq`` stays cheap::

    import daq, rig

    mem = daq.MemorySink()
    daq.acquire(rig.load_scene("ishizaki2009"), seed=1,
                sinks=[daq.Hdf5Sink("run.h5"), mem])       # the file first
    rec = daq.read_run("run.h5")                            # == mem.recording
"""

from __future__ import annotations

from rig.lazy_exports import lazy_exports

#: public name -> (module, attribute)
_EXPORTS = {
    "acquire": ("daq.acquisition", "acquire"),
    "AcquisitionSummary": ("daq.acquisition", "AcquisitionSummary"),
    "AcquisitionInterrupted": ("daq.acquisition", "AcquisitionInterrupted"),
    "Bench": ("daq.benches", "Bench"),
    "DecimatingBench": ("daq.benches", "DecimatingBench"),
    "FunctionBench": ("daq.benches", "FunctionBench"),
    "StreamError": ("daq.benches", "StreamError"),
    "Sink": ("daq.sinks", "Sink"),
    "MemorySink": ("daq.sinks", "MemorySink"),
    "Hdf5Sink": ("daq.hdf5", "Hdf5Sink"),
    "read_run": ("daq.hdf5", "read_run"),
    "run_info": ("daq.hdf5", "run_info"),
    "open_run": ("daq.hdf5", "open_run"),
    "check_file": ("daq.check", "check_file"),
    "FileCheck": ("daq.check", "FileCheck"),
    "clear_write_flags": ("daq.repair", "clear_write_flags"),
    "Recording": ("daq.records", "Recording"),
    "RecordPlan": ("daq.records", "RecordPlan"),
    "Header": ("daq.records", "Header"),
    "Block": ("daq.records", "Block"),
    "Record": ("daq.records", "Record"),
    "Footer": ("daq.records", "Footer"),
    "Channel": ("daq.channels", "Channel"),
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports('daq', _EXPORTS, globals())
