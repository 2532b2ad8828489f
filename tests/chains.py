"""Chains and checks shared by the integrator tests (imported by test modules: pytest puts this
directory on sys.path)."""

import numpy as np

from rig.chain import Chain
from rig.simulate import BaseInput, simulate


def rod_chain(n, *, damping=0.0, mode="relative"):
    """Takeno's uniform rods: 1 m, 1 kg/m (m = 1, l = 1, c = 0.5, J = 1/12)."""
    return Chain((1.0,) * n, (1.0,) * n, (0.5,) * n, (1 / 12,) * n, (damping,) * n, mode)


def random_chain(rng, n, mode):
    m = rng.uniform(0.05, 2.0, n)
    length = rng.uniform(0.05, 1.0, n)
    com = length * rng.uniform(0.1, 0.9, n)
    inertia = m * length**2 * rng.uniform(0.0, 0.2, n)
    return Chain(tuple(m), tuple(length), tuple(com), tuple(inertia),
                 tuple(rng.uniform(0.0, 0.3, n)), mode)


def blockwise_and_one_shot(splits, *, vertical=True, **kw):
    """The damped double rod from (1.0, -0.5) rad on 5 s of seeded random base input (horizontal,
    and vertical unless ``vertical`` is False; 0.01 s samples), run once and in blocks of input
    samples ``splits`` (each block continuing from the previous one's final state). Returns
    (theta of the blocks joined, the blocks' final state, the one-shot trajectory)."""
    chain = rod_chain(2, damping=0.02)
    rng = np.random.default_rng(1)
    ax = 0.5 * rng.standard_normal(500)
    ay = 0.3 * rng.standard_normal(500)
    base = BaseInput(ax, 0.01, ay_mps2=ay if vertical else None)
    one = simulate(chain, 5.0, theta0=(1.0, -0.5), base=base, **kw)
    state, thetas = None, []
    for k0, k1 in splits:
        blk = base.block(k0, k1)
        if state is None:
            tr = simulate(chain, blk.duration_s, theta0=(1.0, -0.5), base=blk, **kw)
            thetas.append(tr.theta_rad)
        else:
            tr = simulate(chain, blk.duration_s, start=state, base=blk, **kw)
            thetas.append(tr.theta_rad[1:])
        state = tr.final_state
    return np.concatenate(thetas), state, one


def random_sturdy_chain(rng, n, mode):
    """Random chains of 0.5-2 kg, 0.3-1.5 m bodies with damping up to 0.5 N m s (no tiny or
    massless bodies: for recursions and couplings checked against dense solves)."""
    m = rng.uniform(0.5, 2.0, n)
    l = rng.uniform(0.3, 1.5, n)
    c = l * rng.uniform(0.1, 0.9, n)
    j = m * l**2 * rng.uniform(0.01, 0.2, n)
    return Chain(m, l, c, j, rng.uniform(0.0, 0.5, n), damping_mode=mode)
