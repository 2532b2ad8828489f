#!/usr/bin/env python3
"""The nonlinear bench's step alone: etdab's loop kernel (``rig.solvers.etdab.etd_ab_kernel``)
against the same step unrolled for the matrices' zero pattern (``rig.solvers.etdab.etdab_kernel``,
what the acquisition runs), each with the remainder at every step and every 5 steps (the default on
this drive, ``rig.bench.model.remainder_every``), on the paper's bench (nonlinear model, 12 states)
over the paper's drive (the source's first ``--seconds`` of seed 2009, held at 1 kHz),
interleaved rounds, medians and quartiles of CPU per DAC sample, the angles' difference, and
whether loop and unrolled give the same bytes.

    .venv/bin/python benchmarks/etdab_kernel.py                 # 9 rounds of 300 s (~30 s)
    .venv/bin/python benchmarks/etdab_kernel.py --rounds 15 --seconds 100
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rig.bench import BenchSimulation, build_model  # noqa: E402
from rig.solvers.etdab import etd_ab_kernel, etdab_kernel  # noqa: E402
from rig.devices.source import generate  # noqa: E402
from rig.scene import load_scene  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--seconds", type=float, default=300.0)
    args = ap.parse_args(argv)
    scene = load_scene("ishizaki2009", ["acquisition.model=nonlinear"])
    sim = BenchSimulation(scene, 2009, method="etdab")
    model = sim.model
    n = int(round(args.seconds * model.fs_hz))
    v, _ = generate(model.source, sim.state.source, n)
    v = np.ascontiguousarray(v, dtype=float)
    prm = model.coupled
    z0 = np.array(sim.state.z, dtype=float)
    every5 = build_model(scene, method="etdab", every=5)
    assert model.every == 5 and every5.every == 5  # the default on the paper's drive
    every1 = build_model(scene, method="etdab", every=1)
    kernels = {  # name: (kernel, model)
        "loop, remainder every step (rig.solvers.etdab.etd_ab_kernel)": (etd_ab_kernel, every1),
        "unrolled, remainder every step (rig.solvers.etdab.etdab_kernel)":
            (etdab_kernel(*every1.etdab[:3], 4, prm.n), every1),
        "loop, remainder every 5 steps": (etd_ab_kernel, every5),
        "unrolled, remainder every 5 steps (the default here)":
            (etdab_kernel(*every5.etdab[:3], 4, prm.n), every5)}

    def run(kernel, m):
        z, hist = z0.copy(), np.zeros((4, prm.rows.size))
        z_out, ax = np.empty((n, z.size)), np.empty(n)
        c = time.process_time()
        kernel(prm.args(), m.etdab, 1, False, hist, np.zeros(1, np.int64), v, z, z_out, ax)
        return time.process_time() - c, (z_out, ax, z, hist)

    outs = {k: run(*f)[1] for k, f in kernels.items()}  # warm-up (compiled code loaded)
    names = list(kernels)
    same = [all(x.tobytes() == y.tobytes() for x, y in zip(outs[names[i]], outs[names[i + 1]]))
            for i in (0, 2)]
    th = model.slices["theta_rad"]
    ref = outs[names[1]][0][:, th]
    err = {k: float(np.sqrt(np.mean((outs[k][0][:, th] - ref) ** 2) / np.mean(ref ** 2)))
           for k in names}
    cpu = {k: [] for k in names}
    for r in range(args.rounds):
        for k in (names if r % 2 == 0 else names[::-1]):
            cpu[k].append(run(*kernels[k])[0] / n * 1e9)
    print(f"paper bench, nonlinear, {model.a.shape[0]} states; {args.seconds:g} s of drive "
          f"({n} steps), {args.rounds} interleaved rounds; CPU per step [ns], medians "
          "[quartiles]; angles against the unrolled step with the remainder every step")
    print("| kernel | CPU per step [ns] | per paper run (3.33 million steps) [s] | angles, "
          "relative RMS difference |")
    print("|---|---|---|---|")
    for k in names:
        q = np.percentile(cpu[k], [25, 50, 75])
        print(f"| {k} | {q[1]:.1f} [{q[0]:.1f}, {q[2]:.1f}] | {q[1] * 3.33e6 * 1e-9:.3f} | "
              f"{err[k]:.2g} |")
    for a, b in ((1, 0), (3, 1)):
        q = np.percentile(np.array(cpu[names[a]]) / np.array(cpu[names[b]]), [25, 50, 75])
        print(f"{names[a]} / {names[b]} per round: {q[1]:.3f} [{q[0]:.3f}, {q[2]:.3f}]")
    print(f"unrolled and loop give the same bytes (states, x0'', final state, history): every "
          f"step {same[0]}, every 5 steps {same[1]}")


if __name__ == "__main__":
    main()
