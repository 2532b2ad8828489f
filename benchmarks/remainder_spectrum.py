#!/usr/bin/env python3
"""How smooth the coupled bench's nonlinear remainder is: the case for stepping it coarser than
the DAC rate. Runs the paper's bench (nonlinear, etdab) over the source's first ``--seconds`` at
``--level`` volts, evaluates the remainder ``f`` (``rig.solvers.coupled.remainder``: the nonlinear
minus the linear derivative, rows v0, omega_1, omega_2, q) at every DAC sample of the trajectory,
and prints per row its rms and the fraction of its power above 5, 20 and 50 Hz (Welch, 16,384-point
segments), next to how far the nonlinear angles are from the linear bench's on the same drive.

    .venv/bin/python benchmarks/remainder_spectrum.py                # 300 s at the paper's 0.1 V
    .venv/bin/python benchmarks/remainder_spectrum.py --level 1.0 --seconds 100
"""

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.signal

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rig.bench import BenchSimulation  # noqa: E402
from rig.solvers.coupled import remainder  # noqa: E402
from rig.solvers.etdab import etdab_kernel  # noqa: E402
from rig.devices.source import generate  # noqa: E402
from rig.scene import load_scene  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--level", type=float, default=0.1, help="source.level_vrms [V]")
    args = ap.parse_args(argv)
    scene = load_scene("ishizaki2009", ["acquisition.model=nonlinear",
                                        f"source.level_vrms={args.level!r}"])
    sim = BenchSimulation(scene, 2009, method="etdab")
    model, prm = sim.model, sim.model.coupled
    fs = model.fs_hz
    n = int(round(args.seconds * fs))
    v, _ = generate(model.source, sim.state.source, n)
    v = np.ascontiguousarray(v, dtype=float)
    sim = BenchSimulation(scene, 2009, method="etdab", every=1)  # the remainder at every step
    phi_t, gam, w, lagv, w_rows, a_cols = sim.model.etdab
    kern = etdab_kernel(phi_t, gam, w, 4, prm.n)
    runs = {}
    for name, weights in (("nonlinear", w), ("linear", np.zeros_like(w))):  # no remainder
        z, hist = np.array(sim.state.z, dtype=float), np.zeros((4, prm.rows.size))
        z_out = np.empty((n, z.size))
        kern(prm.args(), (phi_t, gam, weights, lagv, w_rows, a_cols), 1, False, hist,
             np.zeros(1, np.int64), v, z, z_out, np.empty(n))
        runs[name] = z_out
    th = model.slices["theta_rad"]
    nl, lin = runs["nonlinear"][:, th], runs["linear"][:, th]
    f = np.array([remainder(prm, zk) for zk in runs["nonlinear"]])
    names = ["v0 (stage)", "omega_1", "omega_2", "q (accelerometer)"][:prm.rows.size]
    print(f"paper's bench at {args.level:g} V, {args.seconds:g} s at {fs:g} Hz, seed 2009: "
          f"max |theta| {np.abs(nl).max():.3g} rad; nonlinear - linear angles "
          f"{np.sqrt(np.mean((nl - lin) ** 2) / np.mean(nl ** 2)):.3g} of their rms")
    print("| remainder row | rms | power above 5 Hz | above 20 Hz | above 50 Hz |")
    print("|---|---|---|---|---|")
    for i, name in enumerate(names):
        freqs, p = scipy.signal.welch(f[:, i] - f[:, i].mean(), fs=fs, nperseg=2**14)
        tot = p.sum()
        print(f"| {name} | {np.std(f[:, i]):.3g} | {p[freqs > 5].sum() / tot:.3g} | "
              f"{p[freqs > 20].sum() / tot:.3g} | {p[freqs > 50].sum() / tot:.3g} |")


if __name__ == "__main__":
    main()
