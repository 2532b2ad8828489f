#!/usr/bin/env python3
"""Where the nonlinear acquisition's bench CPU goes, each part alone over the paper's whole run
(3300 s at 1 kHz in the run's blocks, ``daq.benches.BLOCK_S``, or ``--block-s``; seed 2009,
method etdab), medians of ``--rounds`` interleaved rounds of ``time.process_time``:

    .venv/bin/python benchmarks/acquire_nonlinear_parts.py --rounds 5
    .venv/bin/python benchmarks/acquire_nonlinear_parts.py --rounds 5 --block-s 10

Parts: ``source`` (the drive's blocks), ``bench`` (``rig.bench.run.bench_states`` on given source
blocks: the etdab kernel and the per-sample state), ``kinematics`` (the mirror's exact x, z, rot
from theta, numpy), ``noise`` (three ``standard_normal`` draws per block), ``fused kernel``
(``rig.bench.fused.nonlinear_fused_kernel``: the mirror's kinematics, the sensors' noise draws, the
sensors, geometry, clipping, flags, the lifted anti-alias filter, keep; ``kinematics`` and
``noise`` time what it includes, done apart), and the two whole paths: ``fused`` (``BenchSimulation.decimated_blocks``) and
``per-sample`` (``BenchSimulation.blocks`` then daq's filter and decimation).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from daq.acquisition import antialias_for  # noqa: E402
from daq.benches import BLOCK_S  # noqa: E402
from daq.records import RecordPlan  # noqa: E402
from rig.bench import fused as rl  # noqa: E402
from rig.sosfilt import lift_sections  # noqa: E402
from rig.bench import BenchSimulation  # noqa: E402
from rig.bench.run import BenchState, mirror_kinematics, bench_states  # noqa: E402
from rig.devices.source import generate  # noqa: E402
from rig.scene import load_scene  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--block-s", type=float, default=BLOCK_S, help="bench block [s]")
    args = ap.parse_args(argv)
    scene = load_scene("ishizaki2009", ["acquisition.model=nonlinear"])
    plan = RecordPlan.from_acquisition(scene.acquisition)
    aa = antialias_for(scene.acquisition, plan)
    sos = np.ascontiguousarray(aa.sos, dtype=float)
    fs = plan.simulation_rate_hz
    dur = plan.simulation_samples / fs
    n = int(round(args.block_s * fs))
    nb = plan.simulation_samples // n
    model = BenchSimulation(scene, 2009, method="etdab").model
    m = model.slices

    def source():
        st = BenchSimulation(scene, 2009, method="etdab").state.source
        out = []
        for _ in range(nb):
            v, st = generate(model.source, st, n)
            out.append((v, st))
        return out

    srcs = source()
    keep = {}

    def bench():
        state = BenchSimulation(scene, 2009, method="etdab").state
        for src in srcs:
            v, s, z_out, z, accel, native, h = bench_states(model, state, n, src)
            state = BenchState(index=state.index + n, z=z, source=s, rng_states=state.rng_states,
                               native=native, h_next_s=h)
        keep["z_out"], keep["accel"] = z_out, accel

    bench()
    theta = keep["z_out"][:, m["theta_rad"]]

    def kinematics():
        for _ in range(nb):
            mirror_kinematics(scene, theta, exact=True)

    def noise():
        rng = np.random.default_rng(1)
        for _ in range(nb):
            rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)

    acc, lever, q = model.accelerometer, model.lever, model.decimation
    sections = lift_sections(sos, q)
    hp_col = m["accel_highpass_q_mps"].start if acc.n_states else -1
    layout = rl.MirrorLayout(m["theta_rad"].start, hp_col,
                             np.asarray(scene.chain.length_m, dtype=float), scene.mirror.body,
                             float(scene.mirror.position_m))

    def kernel():
        s_aa = np.zeros((3, 2 * sos.shape[0]))
        carry = np.zeros(3, dtype=np.bool_)
        volts, sat = np.empty((3, n // q)), np.empty((3, n // q), dtype=np.bool_)
        mx, mrot = np.empty(n // q), np.empty(n // q)
        rngs = [np.random.default_rng(k) for k in range(3)]
        for _ in range(nb):
            rl.nonlinear_fused_kernel(keep["z_out"], keep["accel"], layout, acc.row_params(fs),
                                      lever.row_params(fs), *rngs, sections, s_aa, carry,
                                      (volts, sat, mx, mrot), q, rl.CHUNK_INTERVALS)

    def fused():
        sim = BenchSimulation(scene, 2009, method="etdab")
        for _ in sim.decimated_blocks(args.block_s, dur, sos):
            pass

    def per_sample():
        st = aa.initial_state(3)
        for b in BenchSimulation(scene, 2009, method="etdab").blocks(args.block_s, dur):
            aa.step(st, np.stack([b.volts[k] for k in "axy"]))

    parts = {"source": source, "bench": bench, "kinematics": kinematics, "noise": noise,
             "fused kernel": kernel, "fused": fused, "per-sample": per_sample}
    for f in parts.values():  # warm-up (compiled kernels loaded)
        f()
    cpu = {k: [] for k in parts}
    names = list(parts)
    for r in range(args.rounds):
        for k in names[r % len(names):] + names[:r % len(names)]:
            c = time.process_time()
            parts[k]()
            cpu[k].append(time.process_time() - c)
    print(f"{args.rounds} rounds, {nb} blocks of {n} samples; CPU medians [quartiles] [s]")
    for k, v in cpu.items():
        print(f"| {k} | {np.median(v):.3f} [{np.percentile(v, 25):.3f}, "
              f"{np.percentile(v, 75):.3f}] |")


if __name__ == "__main__":
    main()
