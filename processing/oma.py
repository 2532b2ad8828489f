"""What an operational modal analysis found, beside the bench's exact modes.

:func:`compare_modes` pairs each exact mode (:class:`rig.bench.modes.BenchModes`, or the
``exact_*`` arrays of a ``daq export --oma`` file) with the identified mode nearest in
frequency and states the errors: relative frequency error, damping ratio error and the modal
assurance criterion (MAC) of the shapes at (x, y). :func:`comparison_table` prints them as
Markdown. The OMA itself is the user's tool's (pyOMA2's FDD, SSI, pLSCF...): this module only
reads its results.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ModeMatch", "compare_modes", "comparison_table", "mac"]


@dataclass(frozen=True)
class ModeMatch:
    """An exact mode and the identified one nearest in frequency (None: none identified)."""

    exact_f_hz: float
    exact_zeta: float
    found_f_hz: float | None
    found_zeta: float | None
    f_relative_error: float | None
    zeta_error: float | None
    mac: float | None


def mac(a, b) -> float:
    """Modal assurance criterion |a^H b|^2 / (|a|^2 |b|^2) of two complex shapes, in [0, 1]."""
    a, b = np.asarray(a, complex), np.asarray(b, complex)
    den = np.vdot(a, a).real * np.vdot(b, b).real
    return float(abs(np.vdot(a, b)) ** 2 / den) if den > 0 else float("nan")


def compare_modes(exact_f_hz, exact_zeta, exact_shapes, found_f_hz, found_zeta,
                  found_shapes=None, *, fmin_hz: float = 0.0) -> list[ModeMatch]:
    """Pair every exact mode at or above ``fmin_hz`` with the nearest identified one.

    ``found_shapes``: (modes, 2) at (x, y) as pyOMA2's ``result.Phi.T`` gives them, or None."""
    ef, ez = np.asarray(exact_f_hz, float), np.asarray(exact_zeta, float)
    es = np.asarray(exact_shapes, complex)
    ff, fz = np.asarray(found_f_hz, float), np.asarray(found_zeta, float)
    out = []
    for k in np.flatnonzero(ef >= fmin_hz):
        if ff.size == 0:
            out.append(ModeMatch(ef[k], ez[k], None, None, None, None, None))
            continue
        j = int(np.argmin(np.abs(ff - ef[k])))
        m = None if found_shapes is None else mac(es[k], np.asarray(found_shapes)[j])
        out.append(ModeMatch(float(ef[k]), float(ez[k]), float(ff[j]), float(fz[j]),
                             float((ff[j] - ef[k]) / ef[k]), float(fz[j] - ez[k]), m))
    return out


def comparison_table(matches: list[ModeMatch], method: str = "OMA") -> str:
    """Markdown table of :func:`compare_modes`."""
    def cell(v, fmt):
        return "-" if v is None else format(v, fmt)

    lines = [f"| exact f [Hz] | {method} f [Hz] | f error | exact zeta | {method} zeta | "
             "MAC |", "|---|---|---|---|---|---|"]
    for m in matches:
        lines.append(f"| {m.exact_f_hz:.5f} | {cell(m.found_f_hz, '.5f')} | "
                     f"{cell(None if m.f_relative_error is None else 100 * m.f_relative_error, '+.3f')} % | "
                     f"{m.exact_zeta:.5f} | {cell(m.found_zeta, '.5f')} | {cell(m.mac, '.4f')} |")
    return "\n".join(lines)
