"""What a scene is, as plain data: resolved settings, physical parameters, derived quantities."""

from __future__ import annotations

import dataclasses

import numpy as np

from rig.errors import ConfigError
from rig.scene import Scene


def scene_summary(scene: Scene) -> dict:
    """The fully resolved scene with derived quantities (JSON-serialisable; SI units).

    Keys: ``scene`` (:meth:`Scene.to_dict`), ``derived`` (S, D, H, natural frequencies, damped
    modes with Q, anti-resonances of the mirror channels) and, for a two-body chain with absolute
    damping, ``design`` (Ishizaki's alpha, beta^2, delta, eps, mu, nu, sigma^2, zeta_i ...).
    """
    c = scene.chain
    f_modes, q_modes = c.modes()
    derived = {
        "S_kgm": c.S.tolist(),
        "D_kgm2": c.D.tolist(),
        "H_kgm2": c.H.tolist(),
        "natural_frequencies_hz": c.natural_frequencies_hz().tolist(),
        "modes": [{"frequency_hz": float(f), "q": float(q)} for f, q in zip(f_modes, q_modes)],
        "antiresonances_hz": {
            "x": c.antiresonances_hz(scene.mirror_weights()).tolist(),
            "y": c.antiresonances_hz(np.eye(c.n)[scene.mirror.body]).tolist(),
        },
        "low_frequency_limits": {
            "x_m_per_mps2": float(-scene.mirror_weights().sum() / c.g_mps2),
            "y_rad_per_mps2": float(-1 / c.g_mps2),
        },
    }
    out = {"scene": scene.to_dict(), "derived": derived}
    design = design_dict(scene)
    if design is not None:
        out["design"] = design
    return out


def design_dict(scene: Scene) -> dict | None:
    """Ishizaki's design parameters of a two-body chain, or None where they are not defined."""
    if scene.chain.n != 2:
        return None
    from rig.ishizaki import design_parameters

    chain = scene.chain
    if chain.damping_mode != "absolute":  # zeta_i are defined for absolute damping
        chain = dataclasses.replace(chain, damping_mode="absolute")
    try:
        d = design_parameters(chain)
    except ConfigError:
        return None
    return {k: float(v) for k, v in dataclasses.asdict(d).items()}


def resonance_table(scene: Scene) -> str:
    """Modes (frequency, Q) and the mirror channels' anti-resonances as a short text."""
    s = scene_summary(scene)["derived"]
    lines = [f"{scene.name}: {scene.chain.n} bodies, {scene.chain.damping_mode} damping"]
    for i, m in enumerate(s["modes"], 1):
        lines.append(f"  mode {i}: {m['frequency_hz']:.4f} Hz, Q = {m['q']:.1f}")
    for ch in ("x", "y"):
        ar = ", ".join(f"{f:.4f}" for f in s["antiresonances_hz"][ch]) or "none"
        lines.append(f"  anti-resonances of {ch}: {ar} Hz")
    return "\n".join(lines)
