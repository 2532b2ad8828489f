"""A design as plain data, as a scene file and as a markdown report (text only; the CLI writes).

:func:`design_dict` (JSON-serialisable; a value with no finite meaning, e.g. the notch of a
policy (ii) design, is ``None`` beside a statement), :func:`design_scene_toml` (a scene file
``daq acquire`` takes: ``base`` = the targets' base scene, the pendulum's design numbers),
:func:`paper_comparison` (where the paper's approximate closed forms differ from the exact linear
model for this design) and :func:`design_markdown`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rig.design.solve import Design
from rig.ishizaki import (antiresonances_hz, closed_form, resonances_hz, rotation_isolation)
from rig.scene_toml import toml_value

__all__ = ["design_dict", "design_scene_toml", "paper_comparison", "design_markdown",
           "design_curves", "design_grid"]


def _finite(x):
    return float(x) if x is not None and math.isfinite(x) else None


def paper_comparison(d: Design) -> list[dict]:
    """Rows (what, paper, exact, unit, note): the paper's closed forms (19), (21), claim (29) and
    the printed (18) against the exact linear model of this design."""
    p = d.params
    rows = []
    res = resonances_hz(p)
    for i, name in enumerate(("lower", "upper")):
        rows.append(dict(what=f"{name} resonance: (19) undamped vs exact damped mode",
                         paper=float(res[i]), exact=d.modes_hz[i], unit="Hz", note=""))
    z2 = float(antiresonances_hz(p)[1])
    rows.append(dict(what="Theta_2 notch: (21) vs exact undamped zero", paper=_finite(z2),
                     exact=_finite(d.notch_hz), unit="Hz",
                     note="at infinity (sigma^2 = 1)" if math.isinf(d.notch_hz) else ""))
    iso = rotation_isolation(p)
    rows.append(dict(what="|theta2/theta1| above f1: claim (29) alpha vs exact limit",
                     paper=iso.alpha_db, exact=_finite(iso.ratio_db), unit="dB",
                     note="exact limit nu^2 (1-sigma^2)/(1-beta^2/sigma^2)"))
    f_hi = np.array([10.0 * p.f1_hz])
    hp, he = (float(20 * np.log10(abs(closed_form(p, f_hi, printed=pr)[1][0])))
              for pr in (True, False))
    rows.append(dict(what=f"|H2| at 10 f1 = {f_hi[0]:.3g} Hz: printed (18) vs exact", paper=hp,
                     exact=he, unit="dB", note="printed B2 has (1-sigma^2) for (1-beta^2)"))
    if math.isfinite(d.notch_hz) and d.notch_hz < 1e3 * p.f1_hz:
        grid = np.linspace(0.97 * d.notch_hz, 1.03 * d.notch_hz, 6001)
        mins = [float(20 * np.log10(np.min(np.abs(closed_form(p, grid, printed=pr)[1]))))
                for pr in (True, False)]
        rows.append(dict(what="min |H2| at the notch: printed (18) vs exact", paper=mins[0],
                         exact=mins[1], unit="dB", note="the printed B2 deepens the notch"))
    return rows


def design_dict(d: Design) -> dict:
    """The design as JSON-serialisable data (SI units; every key's unit in its name)."""
    c = d.chain
    return {
        "status": d.status,
        "targets_source": d.targets.source,
        "policy": d.targets.policy,
        "inputs": {k: v for k, v in dataclasses.asdict(d.inputs).items() if v is not None},
        "physical": {"m1_kg": c.mass_kg[0], "m2_kg": c.mass_kg[1], "r1_m": c.com_m[0],
                     "l_m": c.length_m[0], "r2_m": c.com_m[1], "j1_kgm2": c.inertia_kgm2[0],
                     "j2_kgm2": c.inertia_kgm2[1], "gamma1_nms": c.damping_nms[0],
                     "gamma2_nms": c.damping_nms[1]},
        "groups": {k: _finite(getattr(d.params, k)) for k in
                   ("alpha", "beta2", "eps", "mu", "nu", "sigma2", "delta", "zeta1", "zeta2")},
        "modes": [{"frequency_hz": f, "q": _finite(q)} for f, q in zip(d.modes_hz, d.modes_q)],
        "notch": {"frequency_hz": _finite(d.notch_hz), "depth_db": _finite(d.notch_depth_db),
                  "note": ("none at a finite frequency (J1 = 0)"
                           if math.isinf(d.notch_hz) else "")},
        "checks": [dataclasses.asdict(x) for x in d.checks],
        "performance": [dict(dataclasses.asdict(x), met=x.met) for x in d.performance],
        "binding": list(d.binding),
        "optimised": list(d.optimised),
        "notes": list(d.notes),
        "paper_vs_exact": paper_comparison(d),
    }


def design_scene_toml(d: Design, *, header: str = "") -> str:
    """A scene file of the design: ``base`` = the targets' base scene (its bench and acquisition),
    ``[pendulum]`` kind "ishizaki" with every design number (l = r1: ``l_m`` not set)."""
    t = d.targets
    i = d.inputs
    lines = [f"# {x}".rstrip() for x in header.splitlines()]
    lines += [f"base = {toml_value(t.base)}", "", "[scene]", f"name = {toml_value(t.name)}",
              f"description = {toml_value(t.description or 'designed from ' + t.source)}", "",
              "[pendulum]", 'kind = "ishizaki"', 'damping_mode = "absolute"']
    for key, value in (("r1_m", i.r1_m), ("r2_m", i.r2_m), ("f1_hz", i.f1_hz),
                       ("f2_hz", i.f2_hz), ("eps", i.eps), ("total_mass_kg", i.total_mass_kg),
                       ("q1", i.q1), ("q2", i.q2), ("length2_m", i.length2_m),
                       ("g_mps2", i.g_mps2)):
        lines.append(f"{key} = {toml_value(float(value))}")
    lines += ["", "[mirror]", "body = 2", "position_m = 0.0"]
    return "\n".join(lines) + "\n"


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|")


def _g(x, fmt=".5g"):
    return "-" if x is None else (f"{x:{fmt}}" if isinstance(x, float) else str(x))


def design_markdown(d: Design, *, figure: str | None = None) -> str:
    """A markdown report: the outcome, the notes, the design, its groups, modes and notch, every
    target, where the paper's closed forms differ."""
    dd = design_dict(d)
    out = [f"# Design `{d.targets.name}` from {d.targets.source}", "",
           f"**{'Every target met' if d.status == 'met' else 'Nearest feasible design'}** "
           f"(policy ({d.targets.policy})).", ""]
    out += [f"- {n}" for n in d.notes] + ([""] if d.notes else [])
    if d.binding:
        out += ["Binding: " + "; ".join(d.binding) + ".", ""]
    if d.optimised:
        out += [f"Set by the optimiser (exact linear model): {', '.join(d.optimised)}.", ""]
    out += ["## Pendulum (SI)", "", "| quantity | value |", "|---|---|"]
    out += [f"| {k} | {v:.6g} |" for k, v in dd["physical"].items()]
    out += ["", "## Groups", "", "| group | value |", "|---|---|"]
    out += [f"| {k} | {_g(v)} |" for k, v in dd["groups"].items()]
    out += ["", "## Modes and notch (exact)", "", "| | frequency [Hz] | Q |", "|---|---|---|"]
    out += [f"| mode {n} | {m['frequency_hz']:.5g} | {_g(m['q'], '.4g')} |"
            for n, m in enumerate(dd["modes"], 1)]
    nt = dd["notch"]
    out += [f"| Theta_2 notch | {_g(nt['frequency_hz'])} | depth {_g(nt['depth_db'], '.3g')} dB "
            f"{nt['note']} |", ""]
    out += ["## Targets", "", "| target | wanted | tol | got | (got-wanted)/tol | status |",
            "|---|---|---|---|---|---|"]
    out += [f"| {c.name} | {c.wanted:.6g} | {c.tol:.3g} | {c.got:.6g} | {c.residual:+.3g} | "
            f"{c.status}{'' if c.implied is None else f' (the rest imply {c.implied:.4g})'} |"
            for c in d.checks]
    out += ["", "| performance | value [dB] | limit [dB] | margin [dB] |", "|---|---|---|---|"]
    out += [f"| {_cell(c.what)} | {c.value_db:.4g} | {_g(c.limit_db)} | {c.margin_db:+.3g} |"
            for c in d.performance]
    out += ["", "## The paper's closed forms against the exact linear model", "",
            "| quantity | paper | exact | unit | note |", "|---|---|---|---|---|"]
    out += [f"| {_cell(r['what'])} | {_g(r['paper'])} | {_g(r['exact'])} | {r['unit']} | {r['note']} |"
            for r in dd["paper_vs_exact"]]
    if figure:
        out += ["", f"![design]({figure})"]
    return "\n".join(out) + "\n"


def design_grid(chains, fmin_hz: float, fmax_hz: float, points: int = 2000) -> np.ndarray:
    """The frequencies [Hz] at which :func:`design_curves` of 2-body ``chains`` (one or a
    sequence, drawn on one grid) show every mode, notch and peak of x, theta1, theta2 and the
    ratio theta2/theta1 within 0.1 dB: ``points`` log-spaced ones plus those
    :func:`rig.response_grid.resolving_grid` adds, for each chain, around its modes and the
    zeros of theta1 (x = l theta1's notches, the ratio's peaks) and theta2 (the ratio's
    notches)."""
    from rig.design.model import Pendulums
    from rig.response_grid import resolving_grid

    chains = [chains] if not isinstance(chains, (list, tuple)) else list(chains)
    grids = []
    for chain in chains:
        p = Pendulums.from_chain(chain)

        def response(f, p=p):
            t1, t2 = p.angles(f)
            ratio = p.rotation_ratio(f)[0]
            with np.errstate(divide="ignore", invalid="ignore"):
                # 1/ratio: its notches (the ratio's peaks) are searched like the others'
                return np.stack([p.translation(f)[0], t1[0], t2[0], ratio, 1.0 / ratio], axis=-1)

        f_modes, q = chain.modes()
        notches = np.concatenate([chain.antiresonances_hz(w) for w in np.eye(chain.n)])
        grids.append(resolving_grid(response, fmin_hz, fmax_hz, points,
                                    modes=tuple(zip(f_modes, q)),
                                    notches=tuple(float(f) for f in np.unique(notches))))
    return np.unique(np.concatenate(grids))


def design_curves(chain, freqs_hz) -> dict:
    """The exact responses of a design's 2-body ``chain`` (absolute damping) on ``freqs_hz``
    [Hz]: ``theta1``, ``theta2`` [rad per m/s^2], ``ratio`` theta2/theta1 [-], ``x`` the mirror's
    translation at O2 [m per m/s^2]."""
    from rig.design.model import Pendulums

    p = Pendulums.from_chain(chain)
    f = np.asarray(freqs_hz, float)
    t1, t2 = p.angles(f)
    return {"freqs_hz": f, "theta1": t1[0], "theta2": t2[0], "ratio": p.rotation_ratio(f)[0],
            "x": p.translation(f)[0]}
