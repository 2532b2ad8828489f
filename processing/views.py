"""The analyzer's display views of an :class:`processing.analyzer.Analysis` as figure files
(PNG, PDF or SVG, after the extension).

``bode`` (gain, phase and coherence over the exact model: :func:`bode_figures`),
``nyquist`` (the Nyquist plot with the real and imaginary parts against frequency) and
``coherence`` (both coherences on one axis with their expected curves, each predicted dip
marked with its cause); ``all`` writes the three.
``daq analyze --plot PATH --view V`` uses :func:`view_paths` and :func:`write_views`.
The views only draw: the model curves are the analysis's (:attr:`Analysis.model_curves`, from
its one :class:`rig.bench.SampledResponse`).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from processing.analyzer import incomplete_note, paper_figures
from rig.output_files import atomic_output, check_writable

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
    from processing.plots import Curve, Response

    r = a.model_curves
    f = r.freqs_hz
    b = a.coherence_budget
    ex = {"x": None, "y": None} if b is None else b.expected
    return [Response("H_t", a.h_t, "m/(m/s^2)", Curve("exact model of H_t", f, r.h_t), ex["x"]),
            Response("Θ₂", a.theta_2, "rad/(m/s^2)", Curve("exact model of Θ₂", f, r.theta_2),
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
    """The matplotlib figures of one view (not ``"all"``; built without pyplot)."""
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


def bode_figures(a, *, k: float | None = None, phase: str = "wrapped", into=None):
    """The measured Bode diagrams (:func:`processing.plots.measured_bode_figure`): translation
    H_t (cf. the paper's Fig. 9 for an Ishizaki pendulum) and rotation Theta_2 (cf. Fig. 10),
    measured lines with their Bendat-Piersol band over the exact whole-chain model, stage 1
    dotted (body 1's centre of mass, resp. theta_1, per unit stage acceleration as the analyzer
    reads it), E[H1] dashed, and the coherence; titled from the scene, an incomplete run marked.
    ``phase``: "wrapped" or "unwrapped"; ``into``: two matplotlib SubFigures to draw into (one
    file), else new Figures. Returns ``(fig_translation, fig_rotation)`` (matplotlib Figures,
    no backend selected, or the SubFigures)."""
    from processing.plots import Curve, measured_bode_figure

    scene = a.scene
    r = a.model_curves  # the analysis's exact model over the display band
    f = r.freqs_hz
    kk = a.settings.k if k is None else k
    paper = paper_figures(scene)
    figs = []
    lines = a.freqs_hz
    est = a.settings.estimator.upper()
    into = (None, None) if into is None else into
    for target, (frf, model, stage1, e, what, title, s1, unit) in zip(into, (
            (a.h_t, r.h_t, r.h_g1, None if a.expected is None else a.expected.h_t, "H_t",
             "mirror translation H_t = W_ax/W_aa" + (" (cf. the paper's Fig. 9)" if paper else ""),
             "stage 1: translation of its centre of mass G1 (model)", "m/(m/s^2)"),
            (a.theta_2, r.theta_2, r.theta_1, None if a.expected is None else a.expected.theta_2,
             "Θ₂", "mirror rotation Θ₂ = W_ay/W_aa" + (" (cf. the paper's Fig. 10)" if paper
                                                       else ""),
             "stage 1: rotation θ₁ (model)", "rad/(m/s^2)"))):
        figs.append(measured_bode_figure(
            frf, model=Curve(f"exact model of {what} (whole chain)", f, model),
            stage1=Curve(s1, f, stage1),
            expected=None if e is None else Curve(f"E[H1] of {what} (expected estimate, per "
                                                  "line over its bin)", lines, e),
            k=kk, title=f"{a.run.scene}: {title}\nseed {a.run.seed}, {est}, "
                        f"{a.settings.window} window, {frf.n_averages} averages",
            unit=unit, fmin_hz=a.settings.fmin_hz, fmax_hz=a.settings.fmax_hz, what=what,
            phase=phase, incomplete=incomplete_note(a), into=target))
    return tuple(figs)


def _save_side_by_side(figs, path: Path, *, force: bool, dpi: int) -> None:
    from rig.errors import import_extra

    import_extra("matplotlib", "plot", "drawing figures")
    import matplotlib.image

    imgs = []
    for fig in figs:
        buf = io.BytesIO()
        fig.savefig(buf, dpi=dpi, format="png")
        buf.seek(0)
        imgs.append(matplotlib.image.imread(buf, format="png"))
    height = max(i.shape[0] for i in imgs)
    padded = [np.pad(i, ((0, height - i.shape[0]), (0, 0), (0, 0)), constant_values=1.0)
              for i in imgs]
    with atomic_output(path, force=force) as tmp:
        matplotlib.image.imsave(tmp, np.concatenate(padded, axis=1), format="png")


def _write_view(a, view: str, path: Path, *, phase: str, force: bool, dpi: int) -> None:
    """One view in the format of ``path``'s extension: a PNG's figures drawn and set side by
    side; a vector file's (PDF, SVG) drawn side by side into one figure, as vectors."""
    from processing.figure_files import figure_format, save_figure

    if figure_format(path) == "png":
        _save_side_by_side(view_figures(a, view, phase=phase), path, force=force, dpi=dpi)
        return
    if view != "bode":  # one figure
        save_figure(view_figures(a, view, phase=phase)[0], path, force=force, dpi=dpi)
        return
    from matplotlib.figure import Figure

    from processing.plots import BODE_SIZE_IN

    fig = Figure(figsize=(2 * BODE_SIZE_IN[0], BODE_SIZE_IN[1]), layout="constrained")
    bode_figures(a, phase=phase, into=fig.subfigures(1, 2))
    save_figure(fig, path, force=force, dpi=dpi)


def write_views(a, path, view: str = "bode", *, phase: str = "wrapped", force: bool = False,
                dpi: int = 100) -> list[Path]:
    """Write ``view`` of ``a`` in the format of ``path``'s extension (PNG, PDF or SVG:
    :func:`processing.figure_files.figure_format`; :func:`view_paths`; several figures of one
    view side by side in one file); returns the paths written. Nothing existing is overwritten
    without ``force`` (every path is checked before any is drawn)."""
    from processing.figure_files import figure_format

    figure_format(path)
    paths = view_paths(path, view)
    for p in paths.values():
        check_writable(p, force=force)
    for v, p in paths.items():
        _write_view(a, v, p, phase=phase, force=force, dpi=dpi)
    return list(paths.values())
