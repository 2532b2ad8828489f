"""The etdab step unrolled for one exact-zero pattern (rig.solvers.etdab.etdab_kernel) gives the
loop kernel's values (rig.solvers.etdab.etd_ab_kernel) bit for bit, whatever the pattern, chain,
history lag, steps per DAC interval or block split; its generated module is written once and
reused."""

import math

import numpy as np
import pytest

from rig import unrolled
from rig.bench import build_model
from rig.solvers.etdab import (UNROLL_MAX_STATES, etd_ab_kernel, etd_ab_phase_weights,
                               etdab_kernel, etdab_source)
from rig.scene import load_scene
from rig.linear import discretise

BETA2 = [f"pendulum.r1_m={0.999 * 9.80665 / (2 * math.pi * 2.4783) ** 2!r}", "pendulum.eps=1.001",
         f"pendulum.f2_hz={math.sqrt(0.999 * 9.80665 / 0.000846) / (2 * math.pi)!r}"]
SCENES = {
    "paper": ("ishizaki2009", [], 0.002),
    "driven_3v": ("ishizaki2009", ["source.level_vrms=3.0"], 0.3),
    "no_reaction": ("ishizaki2009", ["stage.reaction=false", "source.level_vrms=1.0"], 0.05),
    "no_accelerometer_highpass": ("ishizaki2009", ["accelerometer.highpass_hz=0"], 0.002),
    "near_degenerate": ("ishizaki2009", BETA2, 0.002),
    "three_bodies": ("rod-chain", ["pendulum.n=3", "initial.theta0_rad=0.3"], 0.3),
}


def _model(name):
    base, over, _ = SCENES[name]
    return build_model(load_scene(base, ["acquisition.model=nonlinear", *over]),
                       method="etdab", every=1)


def _drive(name, n, seed=3):
    """A held voltage whose pendulum swings to the scene's angle: white noise, scaled."""
    return SCENES[name][2] * 30.0 * np.random.default_rng(seed).standard_normal(n)


def _run(kernel, model, v, z, hist, have, nsub=1, mats=None, phase=None):
    phase = np.zeros(1, np.int64) if phase is None else phase
    z_out = np.empty((v.size, z.size))
    ax = np.empty(v.size)
    kernel(model.coupled.args(), tuple(mats or model.etdab), nsub, have, hist, phase, v, z, z_out,
           ax)
    return z_out, ax


def _both(model, v, *, nsub=1, lag=0, mats=None, z0=None):
    mats = mats or model.etdab
    nf = model.coupled.rows.size
    out = []
    for k in ("loop", "unrolled"):
        z = np.zeros(model.a.shape[0]) if z0 is None else z0.copy()
        hist = np.zeros((mats[2].shape[1] + lag, nf))
        kern = (etd_ab_kernel if k == "loop" else
                etdab_kernel(*mats[:3], hist.shape[0], model.coupled.n))
        z_out, ax = _run(kern, model, v, z, hist, False, nsub, mats)
        out.append((z_out, ax, z, hist))
    return out


@pytest.mark.parametrize("name", list(SCENES))
def test_the_unrolled_step_equals_the_loop_kernel_bit_for_bit(name):
    model = _model(name)
    (zl, al, el, hl), (zu, au, eu, hu) = _both(model, _drive(name, 20_000))
    th = model.slices["theta_rad"]
    assert np.max(np.abs(zl[:, th])) > 0.1 * SCENES[name][2]  # it swings: f is not ~0
    for a, b in ((zl, zu), (al, au), (el, eu), (hl, hu)):
        assert a.tobytes() == b.tobytes()


def test_the_unrolled_step_equals_the_loop_kernel_with_substeps_and_a_lagged_history():
    model = _model("driven_3v")
    h = 1.0 / (2 * model.fs_hz)
    phi, g0, _ = discretise(model.a, model.b, h, "zoh")
    w, lagv = etd_ab_phase_weights(model.a, model.coupled.rows, h, 4, 1, lag=1)
    mats = ((np.ascontiguousarray(phi.T), np.ascontiguousarray(g0[:, 0]), w, lagv)
            + tuple(model.etdab[4:]))
    (zl, al, el, hl), (zu, au, eu, hu) = _both(model, _drive("driven_3v", 5000), nsub=2, lag=1,
                                               mats=mats)
    for a, b in ((zl, zu), (al, au), (el, eu), (hl, hu)):
        assert a.tobytes() == b.tobytes()


def test_unrolled_blocks_continue_a_one_shot_run_bit_for_bit():
    model = _model("driven_3v")
    v = _drive("driven_3v", 9000)
    kern = etdab_kernel(*model.etdab[:3], 4, model.coupled.n)
    nf, nz = model.coupled.rows.size, model.a.shape[0]
    one_z, one_h = np.zeros(nz), np.zeros((4, nf))
    one = _run(kern, model, v, one_z, one_h, False)
    z, hist, parts = np.zeros(nz), np.zeros((4, nf)), []
    for i, (a, b) in enumerate(((0, 1), (1, 4000), (4000, 9000))):
        parts.append(_run(kern, model, v[a:b], z, hist, i > 0))
    assert np.concatenate([p[0] for p in parts]).tobytes() == one[0].tobytes()
    assert np.concatenate([p[1] for p in parts]).tobytes() == one[1].tobytes()
    assert z.tobytes() == one_z.tobytes() and hist.tobytes() == one_h.tobytes()


def _every_model(name, every):
    base, over, _ = SCENES[name]
    return build_model(load_scene(base, ["acquisition.model=nonlinear", *over]),
                       method="etdab", every=every)


@pytest.mark.parametrize("name", ["paper", "driven_3v", "three_bodies"])
@pytest.mark.parametrize("every", [2, 5])
def test_a_remainder_every_few_steps_unrolled_equals_the_loop_kernel_bit_for_bit(name, every):
    model = _every_model(name, every)
    assert model.etdab[2].shape[0] == every
    (zl, al, el, hl), (zu, au, eu, hu) = _both(model, _drive(name, 20_000))
    for a, b in ((zl, zu), (al, au), (el, eu), (hl, hu)):
        assert a.tobytes() == b.tobytes()


def test_a_remainder_every_five_steps_continues_across_blocks_that_split_its_nodes():
    model = _every_model("driven_3v", 5)
    v = _drive("driven_3v", 9000)
    kern = etdab_kernel(*model.etdab[:3], 4, model.coupled.n)
    nf, nz = model.coupled.rows.size, model.a.shape[0]
    one_z, one_h, one_p = np.zeros(nz), np.zeros((4, nf)), np.zeros(1, np.int64)
    one = _run(kern, model, v, one_z, one_h, False, phase=one_p)
    z, hist, ph, parts = np.zeros(nz), np.zeros((4, nf)), np.zeros(1, np.int64), []
    for i, (a, b) in enumerate(((0, 1), (1, 4003), (4003, 9000))):  # splits between nodes
        parts.append(_run(kern, model, v[a:b], z, hist, i > 0, phase=ph))
    assert np.concatenate([p[0] for p in parts]).tobytes() == one[0].tobytes()
    assert np.concatenate([p[1] for p in parts]).tobytes() == one[1].tobytes()
    assert z.tobytes() == one_z.tobytes() and int(ph[0]) == int(one_p[0]) == 9000 % 5


def test_each_zero_pattern_has_its_own_kernel_and_a_pattern_is_generated_once():
    paper, free = _model("paper"), _model("no_reaction")
    k1 = etdab_kernel(*paper.etdab[:3], 4, 2)
    k2 = etdab_kernel(*free.etdab[:3], 4, 2)
    assert (paper.etdab[0] != 0).sum() != (free.etdab[0] != 0).sum()  # other zeros
    assert k1 is not k2
    assert etdab_kernel(*paper.etdab[:3], 4, 2) is k1
    # other values, the same zeros: the same kernel
    scaled = tuple(1.5 * x for x in paper.etdab[:3])
    assert etdab_kernel(*scaled, 4, 2) is k1


def test_the_generated_source_leaves_out_exactly_the_zero_products():
    model = _model("paper")
    phi_t, gam, w = model.etdab[:3]
    src = etdab_source(phi_t, gam, w, 4, True)
    n_phi = src.count(" = phi_t[")
    n_w = src.count(" = w[")
    assert n_phi == np.count_nonzero(phi_t) < phi_t.size
    assert n_w == np.count_nonzero(w) < w.size
    compile(src, "<generated>", "exec")  # valid Python


def test_larger_benches_use_the_loop_kernel():
    nz = UNROLL_MAX_STATES + 1
    k = etdab_kernel(np.eye(nz), np.ones(nz), np.ones((1, 4, 3, nz)), 4, 7)
    assert k.py_func is etd_ab_kernel.py_func  # (the lazy kernel or its dispatcher)


def test_a_generated_module_is_written_once_and_not_rewritten(tmp_path):
    p = tmp_path / "m.py"
    unrolled._write_once(p, "x = 1\n")
    stamp = p.stat().st_mtime_ns
    unrolled._write_once(p, "x = 1\n")
    assert p.stat().st_mtime_ns == stamp  # numba's cache key for the module's functions
    unrolled._write_once(p, "x = 2\n")
    assert p.read_text() == "x = 2\n"
    assert [q.name for q in tmp_path.iterdir()] == ["m.py"]  # no temporary left


def test_an_unusable_cache_directory_falls_back_to_a_temporary_one(tmp_path, monkeypatch):
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(blocker))
    d = unrolled._module_dir()
    assert d.is_dir() and blocker not in d.parents
