"""The analyzer's display views of an :class:`processing.analysis.Analysis` as PNG files.

``bode`` (gain, phase and coherence over the exact model: :func:`processing.analysis.bode_figures`),
``nyquist`` (the Nyquist plot with the real and imaginary parts against frequency) and
``coherence`` (both coherences on one axis with their expected curves, each predicted dip
marked with its cause); ``all`` writes the three.
``daq analyze --plot PATH --view V`` uses :func:`view_paths` and :func:`write_views`.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from rig._io import atomic_output, check_writable

VIEWS = ("bode", "nyquist", "coherence", "all")


def view_paths(path, view: str) -> dict[str, Path]:
    """The files a view writes: ``{view: path}``, or for ``"all"`` one per view beside ``path``
    (``bode.png`` -> ``bode-bode.png``, ``bode-nyquist.png``, ``bode-coherence.png``)."""
    if view not in VIEWS:
        raise ValueError(f"view = {view!r} is invalid: expected one of {', '.join(VIEWS)}")
    path = Path(path)
    if view != "all":
        return {view: path}
    return {v: path.with_name(f"{path.stem}-{v}{path.suffix}") for v in VIEWS[:-1]}


def _responses(a):
    from processing.analysis import _FastBench, _fine_grid
    from processing.plots import Curve, Response

    f = _fine_grid(a)
    r = _FastBench(a.scene)(f)
    b = a.coherence_budget
    ex = {"x": None, "y": None} if b is None else b.expected
    return [Response("H_t", a.h_t, "m/(m/s^2)", Curve("exact model of H_t", f, r["h_t"]),
                     ex["x"]),
            Response("Θ₂", a.theta_2, "rad/(m/s^2)", Curve("exact model of Θ₂", f, r["theta_2"]),
                     ex["y"])]


_SHORT = {"geometry": "lever geometry", "accelerometer noise": "accelerometer noise",
          "PSD noise": "PSD noise", "leakage": "leakage"}


def _dip_marks(a) -> tuple:
    """``(frequency, label)`` of each named dip (its main cause), else of the modes."""
    if not a.coherence_dips:
        return tuple((fm, f"mode {fm:.3g} Hz") for fm, _ in a.exact_modes)
    marks = {}
    for d in a.coherence_dips:
        name = "H_t" if d.channel == "x" else "Θ₂"
        cause = _SHORT[d.causes[0][0]] if d.causes else "?"
        key = round(d.frequency_hz, 3)
        marks[key] = (marks[key] + "; " if key in marks else "") + f"{name}: {cause}"
    return tuple(sorted(marks.items()))


def _title(a, what: str) -> str:
    s = a.settings
    return (f"{a.run.scene}: {what}\nseed {a.run.seed}, {s.estimator.upper()}, {s.window} window, "
            f"{a.h_t.n_averages} averages")


def view_figures(a, view: str, *, phase: str = "wrapped") -> list:
    """The matplotlib figures of one view (not ``"all"``); the caller closes them."""
    from processing.analysis import bode_figures, incomplete_note
    from processing.plots import coherence_figure, nyquist_figure

    s, note = a.settings, incomplete_note(a)
    if view == "bode":
        return list(bode_figures(a, phase=phase))
    if view == "nyquist":
        return [nyquist_figure(_responses(a), fmin_hz=s.fmin_hz, fmax_hz=s.fmax_hz,
                               title=_title(a, "Nyquist, real and imaginary parts"),
                               incomplete=note)]
    if view == "coherence":
        return [coherence_figure(_responses(a), fmin_hz=s.fmin_hz, fmax_hz=s.fmax_hz,
                                 marks=_dip_marks(a), title=_title(a, "coherence, measured and "
                                                                     "expected"),
                                 incomplete=note)]
    raise ValueError(f"view = {view!r} is invalid: expected one of {', '.join(VIEWS[:-1])}")


def _save_side_by_side(figs, path: Path, *, force: bool, dpi: int) -> None:
    import matplotlib.image
    import matplotlib.pyplot as plt

    try:
        imgs = []
        for fig in figs:
            buf = io.BytesIO()
            fig.savefig(buf, dpi=dpi, format="png")
            buf.seek(0)
            imgs.append(matplotlib.image.imread(buf, format="png"))
    finally:
        for fig in figs:
            plt.close(fig)
    height = max(i.shape[0] for i in imgs)
    padded = [np.pad(i, ((0, height - i.shape[0]), (0, 0), (0, 0)), constant_values=1.0)
              for i in imgs]
    with atomic_output(path, force=force) as tmp:
        matplotlib.image.imsave(tmp, np.concatenate(padded, axis=1), format="png")


def write_views(a, path, view: str = "bode", *, phase: str = "wrapped", force: bool = False,
                dpi: int = 100) -> list[Path]:
    """Write ``view`` of ``a`` as PNG (:func:`view_paths`; several figures of one view side by
    side in one file); returns the paths written. Nothing existing is overwritten without
    ``force`` (every path is checked before any is drawn)."""
    paths = view_paths(path, view)
    for p in paths.values():
        check_writable(p, force=force)
    for v, p in paths.items():
        _save_side_by_side(view_figures(a, v, phase=phase), p, force=force, dpi=dpi)
    return list(paths.values())
