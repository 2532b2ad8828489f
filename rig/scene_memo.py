"""A memo of pure functions of a scene: computed once per scene and arguments, then copied.

Some results depend on the scene alone, not on the run's seed: the model choice and its
linearisation-error prediction (:func:`rig.bench.select_model`, ~0.15-0.25 s for the paper's
run) and the exact responses on a frequency grid (:func:`rig.bench.expected_response`). A
dataset of thousands of runs of one scene pays for them once per process. The key is the scene's
resolved settings (:attr:`rig.scene.Scene.settings`, which define the scene: ``load_scene`` of
them gives an equal scene) as canonical JSON, less any the function declares its result
independent of (``ignore``: the responses per source volt of the drive's level), plus the other
arguments (arrays by dtype, shape and bytes). A hit returns a deep copy of the first result (the
caller may change it), so a cached call returns exactly what the first call returned, its
recorded wall time included.
At most ``maxsize`` entries per function, least recently used dropped first; thread-safe.

Public API: :func:`per_scene`, :func:`scene_key`.
"""

from __future__ import annotations

import copy
import functools
import json
import threading
from collections import OrderedDict

import numpy as np


def scene_key(scene, ignore: tuple = ()) -> str:
    """Canonical JSON of the scene's resolved settings, without those named in ``ignore``
    (``"section.key"``)."""
    settings = scene.settings
    if ignore:
        settings = {sec: dict(v) if isinstance(v, dict) else v for sec, v in settings.items()}
        for name in ignore:
            sec, _, key = name.partition(".")
            if isinstance(settings.get(sec), dict):
                settings[sec].pop(key, None)
    return json.dumps(settings, sort_keys=True, default=repr)


def _arg_key(a):
    if isinstance(a, np.ndarray):
        return ("ndarray", a.dtype.str, a.shape, a.tobytes())
    if isinstance(a, (list, tuple)):
        return (type(a).__name__,) + tuple(_arg_key(x) for x in a)
    return a


def per_scene(maxsize: int = 16, ignore: tuple = ()):
    """Decorator: memoise ``f(scene, *args, **kwargs)`` on (:func:`scene_key`, args, kwargs)
    (module docstring). ``ignore``: settings (``"section.key"``) that ``f``'s result does not
    depend on, left out of the key, so scenes that differ only there share one entry (e.g. the
    responses per source volt across a sweep of the drive's level). ``f.cache_clear()`` empties
    the memo."""
    def wrap(f):
        memo: OrderedDict = OrderedDict()
        lock = threading.Lock()

        @functools.wraps(f)
        def call(scene, *args, **kwargs):
            key = (scene_key(scene, ignore), _arg_key(args),
                   tuple(sorted((k, _arg_key(v)) for k, v in kwargs.items())))
            with lock:
                hit = memo.get(key)
                if hit is not None:
                    memo.move_to_end(key)
            if hit is None:
                hit = f(scene, *args, **kwargs)
                with lock:
                    memo[key] = hit
                    while len(memo) > maxsize:
                        memo.popitem(last=False)
            return copy.deepcopy(hit)

        call.cache_clear = memo.clear
        return call
    return wrap
