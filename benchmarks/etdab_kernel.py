#!/usr/bin/env python3
"""The nonlinear bench's step alone: etdab's loop kernel (``rig.coupled.etd_ab_kernel``) against
the same step unrolled for the matrices' zero pattern (``rig.unrolled.etdab_kernel``, what the
acquisition runs), on the paper's bench (nonlinear model, 12 states) over the paper's drive
(the source's first ``--seconds`` of seed 2009, held at 1 kHz), interleaved rounds, medians and
quartiles of CPU per DAC sample, and whether the two give the same bytes.

    .venv/bin/python benchmarks/etdab_kernel.py                 # 9 rounds of 300 s (~30 s)
    .venv/bin/python benchmarks/etdab_kernel.py --rounds 15 --seconds 100
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rig import unrolled  # noqa: E402
from rig.bench import BenchSimulation  # noqa: E402
from rig.coupled import etd_ab_kernel  # noqa: E402
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
    kernels = {"loop (rig.coupled.etd_ab_kernel)": etd_ab_kernel,
               "unrolled (rig.unrolled.etdab_kernel)":
                   unrolled.etdab_kernel(*model.etdab[:3], 4, prm.n)}

    def run(kernel):
        z, hist = z0.copy(), np.zeros((4, prm.rows.size))
        z_out, ax = np.empty((n, z.size)), np.empty(n)
        c = time.process_time()
        kernel(*prm.args(), *model.etdab, 1, False, hist, v, z, z_out, ax)
        return time.process_time() - c, (z_out, ax, z, hist)

    outs = {k: run(f)[1] for k, f in kernels.items()}  # warm-up (compiled code loaded)
    a, b = outs.values()
    same = all(x.tobytes() == y.tobytes() for x, y in zip(a, b))
    names = list(kernels)
    cpu = {k: [] for k in names}
    for r in range(args.rounds):
        for k in (names if r % 2 == 0 else names[::-1]):
            cpu[k].append(run(kernels[k])[0] / n * 1e9)
    ratio = np.array(cpu[names[1]]) / np.array(cpu[names[0]])
    print(f"paper bench, nonlinear, {model.a.shape[0]} states; {args.seconds:g} s of drive "
          f"({n} steps), {args.rounds} interleaved rounds; CPU per step [ns], medians "
          "[quartiles]")
    print("| kernel | CPU per step [ns] | per paper run (3.33 million steps) [s] |")
    print("|---|---|---|")
    for k in names:
        q = np.percentile(cpu[k], [25, 50, 75])
        print(f"| {k} | {q[1]:.1f} [{q[0]:.1f}, {q[2]:.1f}] | {q[1] * 3.33e6 * 1e-9:.3f} |")
    q = np.percentile(ratio, [25, 50, 75])
    print(f"unrolled / loop per round: {q[1]:.3f} [{q[0]:.3f}, {q[2]:.3f}]; "
          f"the same bytes (states, x0'', final state, history): {same}")


if __name__ == "__main__":
    main()
