"""The live view in rerun: watch the bench while it runs, replay a run file, show free motion.

This is the only package that imports rerun (``rerun-sdk`` 0.41), and nothing imports it unless a
live option is used. It consumes the acquisition stream (:class:`daq.sinks.Sink`) like a
plot consumes an analysis, which is why it lives in ``processing``: the analyzer's screen needs
the running average (:mod:`processing.running_average`), and ``daq`` must not import
``processing`` (the CLI composes them).

What is shown: ``/bench`` (the bench in a 2D side view to scale, motions magnified), ``/psd``
(the detector with the spot and its trail), ``/signals`` and ``/volts`` (the channels in
engineering units and in ADC volts), ``/analyzer`` (the running averaged H_t and Theta_2 over the
exact model and E[H1], and the coherences) and ``/status``; the entities, their layout
(:func:`acquisition_blueprint`) and what each costs: docs/live-view.md. The sends run on a
worker thread beside the acquisition.

Sinks: a spawned viewer (``spawn``, with an explicit memory limit), a running viewer
(``connect``), an ``.rrd`` file (``rrd``), any combination. A viewer that cannot be spawned,
refuses the connection or goes away gives one warning (:class:`LiveViewWarning`) and the run goes
on: the file sink, if any, keeps everything. ``.rrd`` files are written under a temporary name
and renamed when the stream ends (also when interrupted); an existing file is replaced only with
``force``.

Rooms
-----
- ``stream``: the recording stream to its sinks (:class:`ViewerStream`, :class:`ViewerOptions`),
  the sends in order on a worker thread, the columnar sends;
- ``drawing``: what is drawn (the entities and colours, the bench, the moving parts, the
  analyzer's panels);
- ``sink``: the acquisition stream into rerun (:class:`LiveView`);
- ``blueprint``: the layout (:func:`acquisition_blueprint`);
- ``replay``: a run file replayed (:func:`replay`), free motion shown (:func:`show_trajectory`);
- ``sine_replay``: a stepped-sine run file replayed (:func:`replay_sine`);
- ``screenshot``: a recording rendered into a PNG without a window (:func:`screenshot`).

Their public names are re-exported here: ``from processing.live_view import LiveView``.
"""

import os

# rerun's native log lines would repeat what the live view's single warning says
# (LiveViewWarning); set before any room of this package imports rerun
os.environ.setdefault("RUST_LOG", "off")

from processing.bench_geometry import MAGNIFICATION, BenchDrawing  # noqa: E402
from processing.live_view.blueprint import acquisition_blueprint  # noqa: E402
from processing.live_view.replay import replay, show_trajectory  # noqa: E402
from processing.live_view.screenshot import (recording_summary, screenshot,  # noqa: E402
                                             screenshot_command)
from processing.live_view.sine_replay import SineReplay, replay_sine, sine_blueprint  # noqa: E402
from processing.live_view.sink import LiveView  # noqa: E402
from processing.live_view.stream import (MEMORY_LIMIT, TIMELINE, LiveViewError,  # noqa: E402
                                         LiveViewWarning, ViewerOptions, ViewerStream,
                                         viewer_executable)

__all__ = ["ViewerOptions", "ViewerStream", "LiveView", "LiveViewWarning", "LiveViewError",
           "acquisition_blueprint", "replay", "show_trajectory", "replay_sine", "SineReplay",
           "sine_blueprint", "screenshot",
           "screenshot_command", "recording_summary", "viewer_executable"]


from rig.lazy_exports import submodule_getattr  # noqa: E402

__getattr__ = submodule_getattr('processing.live_view')  # a public submodule is an attribute on first use
