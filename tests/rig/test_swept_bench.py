"""The bench under a swept sine: the stair source, the rate rule and the exact modal response."""

from __future__ import annotations

import numpy as np
import pytest

import rig
from daq.sine import SineAcquisition
from rig.bench.swept import ModalSweep, rule_rate, singularities_hz
from rig.devices.swept_sine import (chirp_path, rate_path, stair_phases, swept_samples)
from rig.errors import ConfigError


@pytest.fixture(scope="module")
def chain():
    scene = rig.load_scene("ishizaki2009", ["acquisition.model=linear"])
    return SineAcquisition(scene, 5, worst_hz=2.48, level_vrms=0.02, duration_s=100.0,
                           fmax_hz=10.0).chain


def test_modal_sweep_equals_the_chain_sample_by_sample(chain):
    # the closed-form modal sum over each output interval against the plain real recursion
    # x <- A x + B v over every DAC sample of a 2 -> 3 Hz chirp: the eigenvector matrix's
    # condition (~4e5) times round-off bounds the difference (measured 3e-11 of the largest
    # channel); bound 1e-9. Split calls carry the modal state.
    q, fs, n = chain.q, chain.fs_hz, 3000
    f = chirp_path(2.0, 3.0, 30.0).frequency((np.arange(n) + 0.5) * q / fs)
    phi, _ = stair_phases(f, 0.3, q, fs)
    level = np.linspace(0.05, 0.02, n)  # the level steps too (auto level along the sweep)
    v = swept_samples(f, phi, q, fs, level)
    modal = ModalSweep(chain)
    fast = np.concatenate([modal.run(f[:1234], phi[:1234], level[:1234]),
                           modal.run(f[1234:], phi[1234:], level[1234:])], axis=1)
    x, slow = np.zeros(chain.a.shape[0]), np.empty((3, n))
    for k in range(n * q):
        if k % q == 0:
            slow[:, k // q] = chain.c @ x
        x = chain.a @ x + chain.b * v[k]
    scale = np.max(np.abs(slow), axis=1)
    assert np.all(np.max(np.abs(fast - slow), axis=1) <= 1e-9 * scale)


def test_stair_source_keeps_its_phase_across_calls():
    f = np.linspace(1.0, 2.0, 100)
    phi, end = stair_phases(f, 0.25, 10, 1000.0)
    a, mid = stair_phases(f[:37], 0.25, 10, 1000.0)
    b, end2 = stair_phases(f[37:], mid, 10, 1000.0)
    assert np.allclose(np.concatenate([a, b]), phi, rtol=0, atol=1e-12)
    assert abs(end2 - end) < 1e-12  # round-off of the running sum only
    v = swept_samples(f, phi, 10, 1000.0, 0.1)
    # sample by sample the phase moves by f_n / fs: no jump where the frequency steps
    ph = np.concatenate([phi[i] + f[i] * np.arange(10) / 1000.0 for i in range(100)])
    assert np.max(np.abs(v - np.sqrt(2) * 0.1 * np.sin(2 * np.pi * ph))) < 1e-12
    assert np.allclose(np.diff(ph), np.repeat(f, 10)[:-1] / 1000.0, rtol=0, atol=1e-12)


def test_rule_memory_at_the_sharp_mode_is_its_amplitude_time_constant(chain):
    # at the 2.479 Hz mode of H_t (a zero of the stage acceleration a) the rule's distance is
    # the half-power half-bandwidth f / 2Q and its memory 1 / (2 pi d) = Q / (pi f), ~68 s;
    # the mode's frequency and Q from the pendulum alone: the chain's zero agrees within 1e-3
    scene = rig.load_scene("ishizaki2009")
    fm, qm = (np.asarray(v)[1] for v in scene.chain.modes())
    sing = singularities_hz(chain)
    d = np.min(np.abs(fm - sing))
    assert abs(1 / (2 * np.pi * d) / (qm / (np.pi * fm)) - 1) < 1e-3
    r = rule_rate(fm, sing, 0.005, 10.0)[0]
    assert r == pytest.approx(0.005 * d * 2 * np.pi * d, rel=1e-12)
    # far from every pole and zero the window (20 s at 1 Hz) is the longer memory
    r1 = rule_rate(1.0, sing, 0.005, 20.0)[0]
    d1 = np.min(np.abs(1.0 - sing))
    assert r1 == pytest.approx(0.005 * d1 / 20.0, rel=1e-12)


def test_paths_reach_their_ends_at_their_rates():
    p = chirp_path(1.0, 4.0, 100.0, "log", "down")
    assert p.frequency(0.0) == pytest.approx(4.0) and p.frequency(100.0) == pytest.approx(1.0)
    assert p.time_at(2.0) == pytest.approx(50.0, rel=1e-4)
    f = np.linspace(1.0, 2.0, 1001)
    r = rate_path(f, np.full(f.size, 0.01))
    assert r.duration_s == pytest.approx(100.0) and r.rate(1.5) == pytest.approx(0.01)
    with pytest.raises(ConfigError, match="rates > 0"):
        rate_path(f, np.zeros(f.size))
