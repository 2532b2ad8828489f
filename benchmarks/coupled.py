#!/usr/bin/env python3
"""The bench kernels alone on 3330 s at 1 kHz (the paper's run, 300 s settle + 30 x 100 s, and
30 s more), the paper's 0.1 V drive, seed 2009: the nonlinear coupled bench by etdab (default) and
lawson4 (the earlier path), the exact linear bench, and their peers.

    .venv/bin/python benchmarks/coupled.py                # ~3 minutes
    .venv/bin/python benchmarks/coupled.py --level 1.0 --no-lsim

1. etdab, lawson4 and the linear kernel over the whole run, interleaved (``--repeats`` rounds,
   rotating order), median CPU (``time.process_time``) and wall; the angles' relative RMS error
   (max over the bodies) against lawson4 at 2 steps per sample (its own error against 4 steps per
   sample on the first 100 s is printed).
2. The peer for the nonlinear bench: ``scipy.integrate.solve_ivp`` on the same equations
   (z' = A z + B V_k + P f(z), f by ``rig.solvers.coupled.remainder``), restarted at every held
   sample (the input jumps there), DOP853 and RK45 over a range of rtol, on the first ``--piece``
   seconds, the cost extrapolated to the run; and once continuous (not restarted: the steps
   straddle the jumps). Errors against lawson4 at 4 steps per sample on the same piece.
3. The peer for the linear bench: ``scipy.signal.lsim`` (zero-order hold) on the same 12-state
   system and input over the whole run, once (``--no-lsim`` skips it, ~15 s).
"""

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rig import bench as rb  # noqa: E402
from rig.bench.estimates import kernel_theta as kernel_only  # noqa: E402
from rig.bench.run import spawn_streams  # noqa: E402
from rig.solvers import coupled as rc  # noqa: E402
from rig.scene import load_scene  # noqa: E402
from rig.devices.source import generate, start_source  # noqa: E402

RUN_S = 3330.0


def rel_rms(d, ref):
    return float(np.max(np.sqrt(np.mean(d**2, axis=0) / np.mean(ref**2, axis=0))))


def kernel_theta(model, v):
    """Angles of the model's kernel alone over the input v from rest, wall and CPU time."""
    z = np.zeros(model.n_states)
    t, c = time.perf_counter(), time.process_time()
    th = kernel_only(model, v, z)
    return th, time.perf_counter() - t, time.process_time() - c


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--level", type=float, default=0.1, help="source level [V rms]")
    ap.add_argument("--piece", type=float, default=1.0, help="solve_ivp piece [s]")
    ap.add_argument("--no-lsim", action="store_true")
    args = ap.parse_args(argv)
    print(f"load average before: {os.getloadavg()}")
    sc = load_scene("ishizaki2009", ["acquisition.model=nonlinear",
                                     f"source.level_vrms={args.level}"])
    models = {"etdab": rb.build_model(sc, method="etdab"),
              "lawson4": rb.build_model(sc, method="lawson4"),
              "linear": rb.build_model(rb.linear_scene(sc))}
    fs = models["etdab"].fs_hz
    n = int(RUN_S * fs)
    _, children = spawn_streams(2009)
    v, _ = generate(models["etdab"].source, start_source(models["etdab"].source, children[0]), n)
    ref_m = rb.build_model(sc, method="lawson4", substeps=2)
    ref, _, _ = kernel_theta(ref_m, v)
    ref4, _, _ = kernel_theta(rb.build_model(sc, method="lawson4", substeps=4), v[:100_000])
    e_ref = rel_rms(ref[:100_000] - ref4, ref4)
    print(f"paper's run {RUN_S:g} s at {args.level:g} V: reference lawson4 2 steps/sample, its "
          f"error on the first 100 s against 4 steps/sample {e_ref:.1e}")
    out = {k: kernel_theta(m, v[:1000]) for k, m in models.items()}  # compile / load
    walls = {k: [] for k in models}
    cpus = {k: [] for k in models}
    names = list(models)
    for r in range(args.repeats):
        for k in names[r % 3:] + names[:r % 3]:
            th, w, c = kernel_theta(models[k], v)
            walls[k].append(w)
            cpus[k].append(c)
            out[k] = th
    print(f"\n| kernel | CPU median [s] | wall median [s] (min, max) | x real time | error vs "
          "reference |")
    print("|---|---|---|---|---|")
    for k in names:
        w, c = np.array(walls[k]), np.array(cpus[k])
        err = rel_rms(out[k] - ref, ref)
        note = " (the model error)" if k == "linear" else ""
        print(f"| {k} | {np.median(c):.3f} | {np.median(w):.3f} ({w.min():.3f}, {w.max():.3f}) | "
              f"{RUN_S / np.median(w):,.0f} | {err:.2g}{note} |")
    med = {k: np.median(cpus[k]) for k in names}
    print(f"CPU ratios of medians: etdab / linear {med['etdab'] / med['linear']:.2f}, "
          f"lawson4 / etdab {med['lawson4'] / med['etdab']:.2f}")

    # -- solve_ivp restarted at every held sample, on a piece
    import scipy.integrate

    m = models["etdab"]
    prm = m.coupled
    a, b = m.a, m.b[:, 0]
    rows = prm.rows
    k_piece = int(args.piece * fs)
    ref_p, _, _ = kernel_theta(rb.build_model(sc, method="lawson4", substeps=4), v[:k_piece])
    h = 1.0 / fs

    def rhs(t, z, vk):
        dz = a @ z + b * vk
        dz[rows] += rc.remainder(prm, z)
        return dz

    rhs(0.0, np.zeros(m.n_states), 0.0)  # compiles the remainder's Python entry point
    scipy.integrate.solve_ivp(rhs, (0.0, h), np.zeros(m.n_states), args=(v[0],))
    print(f"\nsolve_ivp on the first {args.piece:g} s ({k_piece} samples), restarted at every "
          "sample; error against lawson4 4 steps/sample; cost extrapolated to the run")
    print("| solver | rtol | wall [s] piece | extrapolated to the run [s] | error | "
          "x etdab's wall |")
    print("|---|---|---|---|---|---|")
    et_wall = np.median(walls["etdab"])
    for method, rtol in (("RK45", 1e-6), ("RK45", 1e-9), ("DOP853", 1e-9), ("DOP853", 1e-12)):
        z = np.zeros(m.n_states)
        th = np.empty((k_piece, prm.n))
        t0 = time.perf_counter()
        for k in range(k_piece):
            th[k] = z[3:3 + prm.n]
            sol = scipy.integrate.solve_ivp(rhs, (0.0, h), z, method=method, rtol=rtol,
                                            atol=rtol * 1e-6, args=(v[k],))
            z = sol.y[:, -1]
        w = time.perf_counter() - t0
        ext = w * n / k_piece
        print(f"| solve_ivp {method} restarted | {rtol:g} | {w:.2f} | {ext:,.0f} | "
              f"{rel_rms(th - ref_p, ref_p):.2g} | {ext / et_wall:,.0f} |", flush=True)
    # continuous: the held input as a function of time (steps straddle the jumps)
    for method, rtol in (("RK45", 1e-6), ("DOP853", 1e-10)):
        t_eval = np.arange(k_piece) * h

        def rhs_c(t, z):
            return rhs(t, z, v[min(int(t * fs), k_piece - 1)])

        t0 = time.perf_counter()
        sol = scipy.integrate.solve_ivp(rhs_c, (0.0, t_eval[-1]), np.zeros(m.n_states),
                                        method=method, rtol=rtol, atol=rtol * 1e-6,
                                        t_eval=t_eval)
        w = time.perf_counter() - t0
        th = sol.y[3:3 + prm.n].T
        ext = w * n / k_piece
        print(f"| solve_ivp {method} continuous | {rtol:g} | {w:.2f} | {ext:,.0f} | "
              f"{rel_rms(th - ref_p, ref_p):.2g} | {ext / et_wall:,.0f} |", flush=True)

    if not args.no_lsim:
        from scipy import signal

        ml = models["linear"]
        sys_c = signal.StateSpace(ml.a, ml.b, np.eye(ml.n_states), np.zeros((ml.n_states, 1)))
        u = np.append(v, v[-1])
        t_in = np.arange(u.size) * h
        t0, c0 = time.perf_counter(), time.process_time()
        _, y_ls, _ = signal.lsim(sys_c, u, t_in, interp=False)
        w, c = time.perf_counter() - t0, time.process_time() - c0
        th_ls = y_ls[:n, 3:3 + prm.n]
        print(f"\nscipy.signal.lsim (zoh) on the linear bench, whole run, once: wall {w:.2f} s, "
              f"CPU {c:.2f} s ({w / np.median(walls['linear']):,.0f}x the linear kernel's median "
              f"wall); linear kernel - lsim: {rel_rms(out['linear'] - th_ls, th_ls):.2g}")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
