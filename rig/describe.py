"""What a scene is: its resolved settings and derived quantities, and its pendulum's exact response.

:func:`scene_summary` (plain data, JSON-serialisable, SI units), :func:`design_dict` (Ishizaki's
design parameters of a two-body chain) and :func:`resonance_table` (short text) describe the
scene; :func:`mirror_response` gives the analytic frequency responses of its pendulum per unit
base acceleration (linear model). The channels follow SPEC section 5: ``x`` is the horizontal
displacement of the mirror centre relative to the stage [m per m/s^2], ``y`` the rotation of the
mirror's body [rad per m/s^2]. Both have phase 180 deg at low frequency (x -> -s/g, y -> -1/g).
Stage-1 curves (the dotted lines of the paper's Figs. 9 and 10) are the centre of mass of body 1
and theta_1.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError
from rig.linear import FrequencyResponse, wrap_deg
from rig.scene import Scene

__all__ = ["scene_summary", "design_dict", "resonance_table", "MirrorResponse", "mirror_response",
           "log_grid", "model_grid", "gain_db", "phase_deg", "CSV_COLUMNS", "write_csv"]


@dataclass(frozen=True)
class MirrorResponse:
    """Exact linear frequency responses on a frequency grid.

    Attributes
    ----------
    freqs_hz : (nf,) frequencies [Hz].
    x : (nf,) mirror translation relative to the stage [m per m/s^2].
    y : (nf,) mirror rotation, theta of the mirror body [rad per m/s^2].
    stage1_x : (nf,) horizontal displacement of body 1's centre of mass [m per m/s^2].
    stage1_theta : (nf,) theta_1 [rad per m/s^2].
    last_com_x : (nf,) horizontal displacement of the last body's centre of mass [m per m/s^2]
        (Ishizaki's H1 + H2 for n = 2).
    theta : (nf, n) every angle [rad per m/s^2].
    """

    freqs_hz: np.ndarray
    x: np.ndarray
    y: np.ndarray
    stage1_x: np.ndarray
    stage1_theta: np.ndarray
    last_com_x: np.ndarray
    theta: np.ndarray

    def response(self) -> FrequencyResponse:
        """The mirror channels ``x`` [m per m/s^2] and ``y`` [rad per m/s^2] as one
        :class:`rig.linear.FrequencyResponse` (columns "x", "y")."""
        return FrequencyResponse(self.freqs_hz, np.stack([self.x, self.y], axis=-1), ("x", "y"),
                                 "per m/s^2")


def log_grid(fmin_hz: float, fmax_hz: float, points: int) -> np.ndarray:
    """``points`` log-spaced frequencies from fmin_hz to fmax_hz inclusive [Hz]."""
    if not (np.isfinite(fmin_hz) and fmin_hz > 0):
        raise ConfigError(f"fmin = {fmin_hz} Hz is invalid: expected a finite frequency > 0")
    if not (np.isfinite(fmax_hz) and fmax_hz > fmin_hz):
        raise ConfigError(f"fmax = {fmax_hz} Hz is invalid: expected a finite frequency > fmin "
                          f"({fmin_hz} Hz)")
    if points < 2:
        raise ConfigError(f"points = {points} is invalid: expected >= 2")
    return np.geomspace(fmin_hz, fmax_hz, points)


def model_grid(scene: Scene, fmin_hz: float, fmax_hz: float, points: int) -> np.ndarray:
    """The frequencies [Hz] at which :func:`mirror_response` is sampled for a person (``daq
    model``'s CSV and figure): ``points`` log-spaced ones from fmin_hz to fmax_hz (the base grid,
    :func:`log_grid`) plus those :func:`rig.response_grid.resolving_grid` adds so that every mode
    and anti-resonance of x, y and the stage-1 curves is drawn within 0.1 dB."""
    from rig.response_grid import resolving_grid, scene_features

    base = log_grid(fmin_hz, fmax_hz, points)
    chain = scene.chain
    weights = (scene.mirror_weights(), np.eye(chain.n)[scene.mirror.body],
               chain.point_weights(0, chain.com_m[0]), np.eye(chain.n)[0])
    modes, notches = scene_features(scene, weights)

    def response(f):
        r = mirror_response(scene, f)
        return np.stack([r.x, r.y, r.stage1_x, r.stage1_theta], axis=-1)

    return resolving_grid(response, float(base[0]), float(base[-1]), points, modes=modes,
                          notches=notches)


def mirror_response(scene: Scene, freqs_hz) -> MirrorResponse:
    """Exact linear responses of the scene's pendulum at ``freqs_hz`` (direct complex solve)."""
    chain = scene.chain
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    theta = chain.frf_angles(f)
    last = chain.n - 1
    return MirrorResponse(
        freqs_hz=f,
        x=theta @ scene.mirror_weights(),
        y=theta[:, scene.mirror.body],
        stage1_x=theta @ chain.point_weights(0, chain.com_m[0]),
        stage1_theta=theta[:, 0],
        last_com_x=theta @ chain.point_weights(last, chain.com_m[last]),
        theta=theta,
    )


def gain_db(h) -> np.ndarray:
    """20 log10 |h| [dB]."""
    return 20 * np.log10(np.abs(h))


def phase_deg(h) -> np.ndarray:
    """Phase wrapped to (-180, 180] [deg]."""
    return wrap_deg(np.degrees(np.angle(h)))


# -- the scene as data ----------------------------------------------------------------------


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
#: Columns of :func:`write_csv` (``daq model --csv``; README "daq model CSV columns").
CSV_COLUMNS = ("frequency_hz", "x_re", "x_im", "x_gain_db", "x_phase_deg",
               "y_re", "y_im", "y_gain_db", "y_phase_deg")


def write_csv(resp: MirrorResponse, path, *, force: bool = False):
    """Write ``resp`` as CSV, one row per frequency (:data:`CSV_COLUMNS`; every value as
    ``repr(float)``, so it reads back bit for bit); never over an existing file without
    ``force``, and the file appears whole or not at all (:func:`rig.output_files.atomic_output`).
    Returns the path."""
    from rig.output_files import write_columns_csv

    cols = [resp.freqs_hz, resp.x.real, resp.x.imag, gain_db(resp.x), phase_deg(resp.x),
            resp.y.real, resp.y.imag, gain_db(resp.y), phase_deg(resp.y)]
    return write_columns_csv(path, CSV_COLUMNS, cols, force=force)
