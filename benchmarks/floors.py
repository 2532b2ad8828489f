#!/usr/bin/env python3
"""Where the paper run's remaining time is bound by work that keeps its bytes: the alternatives
tried in speed rounds 7 and 8 for the three largest parts, each against the project's path, in one
warm process, interleaved, CPU medians.

    .venv/bin/python benchmarks/floors.py               # all three parts (~1 minute)
    .venv/bin/python benchmarks/floors.py --part etd4m --rounds 21

``fft``: the source's noise (a 131,072-tap FIR at 1 kHz by overlap-save,
:func:`rig.devices.source._noise`) for the paper run's 3.33e6 samples, with frames of 2 to 8
times the taps (the source's is 4, :data:`rig.devices.source.FRAME_FACTOR`), each frame by one
rfft, product and irfft (the path before speed round 8) or two frames by one complex FFT,
product and inverse (:data:`rig.devices.source.FRAMES_PER_FFT`); the frames, and so the
samples' round-off, follow both.

``normals``: the 1.0e7 standard normal draws of the linear run's three sensor streams (3.33e6
samples each), drawn as the fused kernel draws them (numba's Generator, one stream after the
other; :func:`rig.devices.source._fill_standard_normal`), by numpy's own
``Generator.standard_normal(out=)``, and by PCG64 and numpy's ziggurat written out in compiled
code with the 128-bit step as LLVM's i128 arithmetic, the three streams interleaved in one loop
(independent chains side by side). Each must give numpy's values and leave each generator in
numpy's state (checked).

``etd4m``: the pendulum's nonlinear paper run (target 3) by its kernel
(:func:`rig.solvers.etd4m.etd4m_kernel2h`, 3000 s, m = 10, 0.01 s rows) with its per-step
input FIR (480 multiply-adds a step) in the loop (speed round 6) and as BLAS products (now),
against the same kernel with the FIR taken out and read from an array computed beforehand: the
bound of the serial chain if the FIR were free (the loop's rows, checked).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.interleave import interleaved  # noqa: E402


def _timed(fn):
    """``fn()``'s (wall, CPU) seconds, as :func:`benchmarks.interleave.interleaved` takes them."""
    t, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t, time.process_time() - c


def _median_cpu(fns: dict, rounds: int) -> dict:
    """CPU per call of each function, medians of interleaved rounds (A B, B A, ...) after one
    warm-up call each."""
    for f in fns.values():
        f()
    _, cpus = interleaved(list(fns), rounds, lambda k: _timed(fns[k]), rotate=False)
    return {k: float(np.median(v)) for k, v in cpus.items()}


def fft_part(rounds: int) -> None:
    import rig.devices.source as src
    from rig.bench.model import build_model
    from rig.scene import load_scene

    source = build_model(load_scene("ishizaki2009", ["acquisition.model=linear"])).source
    n, block = 3_330_001, 100_000  # the paper run's DAC samples, in the run's 100 s blocks
    # (frame length / taps, frames per FFT): one real FFT a frame (1, the path before speed
    # round 8) or two frames in one complex FFT (2, the source's now)
    configs = ((4, 1), (4, 2), (2, 2), (3, 2), (5, 1), (5, 2), (8, 2))
    made = {}

    def run(config):
        src.FRAME_FACTOR, src.FRAMES_PER_FFT = config
        src.noise_fir.cache_clear()
        src.noise_fir_rfft.cache_clear()
        source.taps  # the filter's design, outside the timing

        def generate():
            st, parts = src.start_source(source, 1), []
            for i in range(0, n, block):
                v, st = src.generate(source, st, min(block, n - i))
                parts.append(v)
            made[config] = np.concatenate(parts)
        return _timed(generate)

    own = (src.FRAME_FACTOR, src.FRAMES_PER_FFT)
    try:
        for c in configs:  # warm-up
            run(c)
        _, cpu = interleaved(list(configs), rounds, run, rotate=False)
    finally:
        src.FRAME_FACTOR, src.FRAMES_PER_FFT = own
        src.noise_fir.cache_clear()
        src.noise_fir_rfft.cache_clear()
    ref = made[own]
    rms = float(np.sqrt(np.mean(ref**2)))
    print(f"the source's noise ({source.n_taps} taps), the paper run's {n:,} samples in 100 s "
          f"blocks, CPU, medians of {rounds}, by the overlap-save frame length and the frames "
          f"per FFT (1: a real FFT each, 2: a pair in one complex FFT):")
    for c in configs:
        mark = "  (the source's)" if c == own else ""
        d = float(np.max(np.abs(made[c] - ref))) / rms
        print(f"  frame = {c[0]} x taps, {c[1]} per FFT: {np.median(cpu[c]) * 1e3:.1f} ms, "
              f"samples within {d:.1g} of the rms of the source's{mark}")


def _pcg64_kernels():
    """numpy's PCG64 (128-bit LCG, XSL-RR output) and its ziggurat for doubles, compiled."""
    from llvmlite import ir
    from numba import njit, types
    from numba.extending import intrinsic
    from numba.np.random._constants import (fi_double, ki_double, wi_double,
                                            ziggurat_nor_inv_r, ziggurat_nor_r)

    mult = 0x2360ED051FC65DA44385DF649FCCF645  # numpy's PCG64 multiplier
    mhi, mlo = np.uint64(mult >> 64), np.uint64(mult & (2**64 - 1))
    u64 = types.uint64

    @intrinsic
    def step128(typingctx, shi, slo, ihi, ilo, ahi, alo):
        sig = types.UniTuple(u64, 2)(u64, u64, u64, u64, u64, u64)

        def codegen(context, builder, signature, args):
            i128 = ir.IntType(128)

            def join(h, lo):
                return builder.or_(builder.shl(builder.zext(h, i128), ir.Constant(i128, 64)),
                                   builder.zext(lo, i128))
            r = builder.add(builder.mul(join(args[0], args[1]), join(args[4], args[5])),
                            join(args[2], args[3]))
            hi = builder.trunc(builder.lshr(r, ir.Constant(i128, 64)), ir.IntType(64))
            return context.make_tuple(builder, signature.return_type,
                                      [hi, builder.trunc(r, ir.IntType(64))])
        return sig, codegen

    @njit(inline="always")
    def next64(st):
        hi, lo = step128(st[0], st[1], st[2], st[3], mhi, mlo)
        st[0], st[1] = hi, lo
        x = hi ^ lo
        rot = hi >> np.uint64(58)
        return (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))

    @njit(inline="always")
    def unit(st):
        return (next64(st) >> np.uint64(11)) * (1.0 / 9007199254740992.0)

    @njit(inline="always")
    def normal(st):
        while True:
            r = next64(st)
            idx = r & np.uint64(0xff)
            r >>= np.uint64(8)
            sign = r & np.uint64(1)
            rabs = (r >> np.uint64(1)) & np.uint64(0x000fffffffffffff)
            x = rabs * wi_double[idx]
            if sign:
                x = -x
            if rabs < ki_double[idx]:
                return x
            if idx == 0:
                while True:
                    xx = -ziggurat_nor_inv_r * np.log1p(-unit(st))
                    yy = -np.log1p(-unit(st))
                    if yy + yy > xx * xx:
                        if (rabs >> np.uint64(8)) & np.uint64(1):
                            return -(ziggurat_nor_r + xx)
                        return ziggurat_nor_r + xx
            elif ((fi_double[idx - 1] - fi_double[idx]) * unit(st) + fi_double[idx]
                  < np.exp(-0.5 * x * x)):
                return x

    @njit(nogil=True)
    def three_interleaved(s1, s2, s3, o1, o2, o3):
        for i in range(o1.shape[0]):
            o1[i] = normal(s1)
            o2[i] = normal(s2)
            o3[i] = normal(s3)

    @njit(nogil=True)
    def three_generators(g1, g2, g3, o1, o2, o3):
        for i in range(o1.shape[0]):
            o1[i] = g1.standard_normal()
        for i in range(o2.shape[0]):
            o2[i] = g2.standard_normal()
        for i in range(o3.shape[0]):
            o3[i] = g3.standard_normal()

    return three_interleaved, three_generators


def _pcg_state(bg) -> np.ndarray:
    s = bg.state["state"]
    m = 2**64 - 1
    return np.array([s["state"] >> 64, s["state"] & m, s["inc"] >> 64, s["inc"] & m], np.uint64)


def normals_part(rounds: int) -> None:
    interleaved, generators = _pcg64_kernels()
    n = 3_330_000
    seeds = (11, 12, 13)
    outs = [[np.empty(n) for _ in seeds] for _ in range(3)]
    gens = [np.random.Generator(np.random.PCG64(s)) for s in seeds]
    gens_np = [np.random.Generator(np.random.PCG64(s)) for s in seeds]
    states = [_pcg_state(np.random.PCG64(s)) for s in seeds]
    generators(*gens, *outs[0])
    for g, o in zip(gens_np, outs[1]):
        g.standard_normal(out=o)
    interleaved(*states, *outs[2])
    same = all(np.array_equal(a, b) for o in outs[1:] for a, b in zip(outs[0], o))
    same_state = all(np.array_equal(s, _pcg_state(g.bit_generator))
                     for s, g in zip(states, gens))
    cpu = _median_cpu({
        "numba Generator, stream after stream (the kernel's)":
            lambda: generators(*gens, *outs[0]),
        "numpy Generator.standard_normal(out=)":
            lambda: [g.standard_normal(out=o) for g, o in zip(gens_np, outs[1])],
        "PCG64 + ziggurat compiled, three streams interleaved":
            lambda: interleaved(*states, *outs[2]),
    }, rounds)
    print(f"3 x {n:,} standard normals, CPU, medians of {rounds} (the same values: {same}; "
          f"the generators' states equal: {same_state}):")
    for k, t in cpu.items():
        print(f"  {k}: {t * 1e3:.1f} ms ({t / (3 * n) * 1e9:.2f} ns a draw)")


def etd4m_part(rounds: int) -> None:
    import rig.solvers.etd4m as e4
    from benchmarks.targets import paper_input
    from rig.scene import load_scene
    from rig.simulate import simulate
    from rig.solvers.etd4m import etd4m_kernel2h

    chain = load_scene("ishizaki2009").chain
    base = paper_input(3000.0)
    got = {}

    def capture(*a):
        got["args"] = a
        return etd4m_kernel2h(*a)
    with mock.patch.object(e4, "etd4m_kernel2h", capture):
        simulate(chain, 3000.0, theta0=0.0, base=base, method="etd4m", dt_s=0.01,
                 output_dt_s=0.01, estimate_error=False)
    a = got["args"]
    wt, ax, m, n_steps = a[1].wt, a[2], a[3], a[4]
    y, y_out, hist = a[6], a[7], a[8]
    pre = _fir_free_kernel()
    idx = np.arange(n_steps)[:, None] * m + np.arange(wt.shape[0])[None, :]
    accs = ax[idx] @ wt
    rows = {}

    def run(which):
        yy, yo, hh = y.copy(), y_out.copy(), hist.copy()
        if which == "fir-free":
            pre(*a[:5], accs, a[5], yy, yo, hh, a[9], 0)
        else:
            etd4m_kernel2h(*a[:6], yy, yo, hh, a[9], 0 if which == "loop" else a[10])
        rows[which] = yo
    cpu = _median_cpu({k: (lambda k=k: run(k)) for k in ("loop", "blas", "fir-free")}, rounds)
    same = np.array_equal(rows["loop"], rows["fir-free"])
    d = float(np.max(np.abs(rows["blas"] - rows["loop"]) / np.max(np.abs(rows["loop"]), axis=0)))
    print(f"etd4m m = {m}, the paper's 3000 s ({n_steps:,} steps), kernel CPU, medians of "
          f"{rounds}:")
    for k, what in (("loop", "its FIR in the loop (speed round 6)"),
                    ("blas", f"its FIR as BLAS products of {a[23]} steps (now)"),
                    ("fir-free", "its FIR read from an array made beforehand (not timed)")):
        print(f"  {what}: {cpu[k] * 1e3:.1f} ms ({3000 / cpu[k]:,.0f}x real time)")
    print(f"  rows: the FIR-free kernel's equal the loop's: {same}; the BLAS FIR's within {d:.1g} "
          "of each column's largest |value|")


def _fir_free_kernel():
    """etd4m_kernel2h with ``acc = given[k]`` in place of its FIR (compiled from its source)."""
    import inspect

    import rig.solvers.etd4m as k
    from numba import njit

    src = inspect.getsource(k.etd4m_kernel2h.py_func if hasattr(k.etd4m_kernel2h, "py_func")
                            else k.etd4m_kernel2h)
    src = src[src.index("def "):]
    src = src.replace("def etd4m_kernel2h(", "def etd4m_kernel2h_fir_free(", 1)
    src = src.replace("ax, m, n_steps,", "ax, m, n_steps, given,", 1)
    branch, call = "        if kc > 0:\n", "            _etd4m_fir48(ax, i0, 1, wt, acc)\n"
    if branch not in src or call not in src:
        raise RuntimeError("etd4m_kernel2h no longer forms its FIR as expected")
    src = src.replace(branch, "        if False:\n").replace(call, "            acc = given[k]\n")
    ns = dict(vars(k))
    exec(compile(src, "<etd4m_kernel2h_fir_free>", "exec"), ns)
    return njit(nogil=True, fastmath={"contract"})(ns["etd4m_kernel2h_fir_free"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--part", choices=("fft", "normals", "etd4m", "all"), default="all")
    ap.add_argument("--rounds", type=int, default=11)
    args = ap.parse_args(argv)
    print(f"load average before: {os.getloadavg()}")
    for part, fn in (("fft", fft_part), ("normals", normals_part), ("etd4m", etd4m_part)):
        if args.part in (part, "all"):
            fn(args.rounds)
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
