"""Checks of a finished simulation: is its own error estimate small against the motion?

:func:`simulation_warnings` returns the sentences a user must read before trusting a trajectory
(``daq simulate`` prints each as a ``WARNING:`` line and stores them with the trajectory):

* the estimated angle error (the integrator's own estimate, :attr:`Trajectory.error_estimate_rad`)
  exceeds :data:`WARN_FRACTION` of the motion, the largest peak-to-peak swing of any body's
  angle: the trajectory is not resolved (for a chaotic pendulum, the run is longer than the
  predictability horizon of this method and tolerance);
* the ``linear`` method on an undamped chain on a fixed base (whose true energy is conserved)
  changes the chain's nonlinear energy by more than :data:`WARN_FRACTION` of its energy above
  rest: the motion is too large for the linearised model (a model error, which the linear
  method's round-off estimate does not include).
"""

from __future__ import annotations

import numpy as np

#: Stated fraction of the motion above which a simulation's own error estimate is reported.
WARN_FRACTION = 0.01


def simulation_warnings(traj, *, fixed_base: bool = True,
                        fraction: float = WARN_FRACTION) -> tuple[str, ...]:
    """Warnings about ``traj`` (a :class:`rig.simulate.Trajectory`) as plain sentences."""
    out = []
    theta = np.asarray(traj.theta_rad)
    motion = 0.0
    if traj.error_estimate_rad is not None and theta.shape[0] > 1:
        # per body along its own contiguous row: a strided reduction over the rows of a long run
        # costs about as much as a fast integration of it
        motion = float(np.max(np.ptp(np.ascontiguousarray(theta.T), axis=1)))
    if motion > 0:
        err = traj.max_error_rad
        if err > fraction * motion:
            t_bad = float(traj.t_s[np.argmax(np.max(traj.error_estimate_rad, axis=1)
                                             > fraction * motion)])
            out.append(f"the estimated angle error {err:.3g} rad is {err / motion:.3g} of the "
                       f"motion ({motion:.3g} rad peak to peak; stated limit {fraction:g}), "
                       f"first over the limit at t = {t_bad:.6g} s: the trajectory is not "
                       "resolved beyond there (a chaotic motion past its predictability "
                       "horizon, or too coarse a step); tighten rtol or dt, or shorten the run")
    chain = traj.chain
    undamped = not np.any(np.asarray(chain.damping_nms) != 0)
    if traj.method == "linear" and fixed_base and undamped and theta.shape[0] > 1:
        e = np.asarray(traj.energy_j)
        n = chain.n
        e_rest = float(chain.energy(np.zeros(n), np.zeros(n)))
        above = float(e[0] - e_rest)
        drift = float(np.max(np.abs(e - e[0])))
        if above > 0 and drift > fraction * above:
            out.append(f"the linear model changes the chain's energy by {drift:.3g} J, "
                       f"{drift / above:.3g} of its energy above rest ({above:.3g} J; stated "
                       f"limit {fraction:g}): the motion is too large for the linearised model; "
                       "use a nonlinear method (dop853, etd3)")
    return tuple(out)
