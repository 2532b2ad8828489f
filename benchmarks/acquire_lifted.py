#!/usr/bin/env python3
"""The paper's linear acquisition (30 x 100 s at 100 Hz from the 1 kHz bench, 330 s settling,
seed 2009, written to a run file) in one warm process: the lifted, fused chain (rig.bench.fused, the
default) against the per-sample path it replaces (``rig_bench(lifted=False)``, with the
per-scene memo of the model choice and responses emptied before each of its runs, as every
run paid before), interleaved; and the peer for the linear bench, ``scipy.signal.lsim``.

    .venv/bin/python benchmarks/acquire_lifted.py               # 9 rounds, ~1 minute
    .venv/bin/python benchmarks/acquire_lifted.py --rounds 15 --lsim-s 100
    .venv/bin/python benchmarks/acquire_lifted.py --parts 5 --rounds 0 --lsim-s 0   # where it goes

Every round runs both once, in alternating order, after one warm-up run each (numba's cache
loaded, the filter design memoised). Printed: median and quartiles of CPU
(``time.process_time``, every thread of the process) and wall time per run, the median of the
per-round ratios (lifted / per-sample), runs per minute on 2 cores (2 x 60 s / median CPU), and
how far the two runs' arrays differ (truth: largest difference over the series' rms; codes:
samples that differ, by at most how much).

The peer: ``scipy.signal.lsim`` (zero-order hold, the bench's 12-state system, the run's own
DAC samples) on the first ``--lsim-s`` seconds, its states at the kept instants against the
lifted chain's (the same equations; its difference is round-off too), its CPU time extrapolated
to the run's 3.33 million samples; it gives the bench's states only (no sensors, noise or
filter), so the comparison favours it.
"""

import argparse
import functools
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.interleave import interleaved, ratio_rows  # noqa: E402
from daq.acquisition import acquire  # noqa: E402
from daq.benches import BLOCK_S, rig_bench  # noqa: E402
from daq.hdf5 import Hdf5Sink, read_run  # noqa: E402
from rig import bench as rb  # noqa: E402
from rig.bench import fused as rl  # noqa: E402
from rig.bench.run import spawn_streams  # noqa: E402
from rig.sosfilt import lift_sections  # noqa: E402
from rig.devices.source import generate, start_source  # noqa: E402
from rig.scene import load_scene  # noqa: E402

SCENE = ("ishizaki2009", ["acquisition.model=linear"])


def one_run(name, out):
    scene = load_scene(*SCENE)
    if name == "per-sample":
        rb.select_model.cache_clear()
        rb.expected_response.cache_clear()
    kw = {"lifted": name == "lifted"}
    t, c = time.perf_counter(), time.process_time()
    acquire(scene, seed=2009, sinks=[Hdf5Sink(out, force=True)],
            bench=functools.partial(rig_bench, **kw))
    return time.perf_counter() - t, time.process_time() - c


def compare_files(a, b):
    ra, rb_ = read_run(a), read_run(b)
    worst = 0.0
    for k, v in ra.truth.items():
        v, w = np.asarray(v), np.asarray(rb_.truth[k])
        scale = np.sqrt(np.mean(v**2))
        if scale > 0:
            worst = max(worst, float(np.max(np.abs(v - w)) / scale))
    ndiff, dmax, total = 0, 0, 0
    for k, v in ra.codes.items():
        d = np.abs(np.asarray(v, np.int64) - np.asarray(rb_.codes[k], np.int64))
        ndiff, dmax, total = ndiff + int(np.sum(d > 0)), max(dmax, int(d.max())), total + d.size
    flags = all(np.array_equal(ra.clipped[k], rb_.clipped[k])
                and np.array_equal(ra.saturated[k], rb_.saturated[k]) for k in ra.codes)
    return worst, ndiff, dmax, total, flags


def lsim_peer(seconds):
    from scipy import signal

    scene = load_scene(*SCENE)
    model = rb.build_model(scene)
    q = model.decimation
    n = int(round(seconds * model.fs_hz))
    _, children = spawn_streams(2009)
    v, src = generate(model.source, start_source(model.source, children[0]), n)
    t = np.arange(n) / model.fs_hz
    sys_c = signal.StateSpace(model.a, model.b, np.eye(model.n_states),
                              np.zeros((model.n_states, 1)))
    c = time.process_time()
    _, _, x = signal.lsim(sys_c, v, t, X0=np.zeros(model.n_states), interp=False)
    cpu = time.process_time() - c
    lifted = rl.lift(model, q)
    st = rb.start(model, 2009)
    aa = np.zeros((0, 6))
    blk, _, _ = rl.advance_decimated(model, lifted, st, rl.start_decimated(aa), n,
                                     lift_sections(aa, q), (v, src))
    th = x[::q, model.slices["theta_rad"]]
    err = np.max(np.abs(th - blk.truth["theta_rad"])) / np.sqrt(np.mean(th**2))
    return cpu, cpu * 3.33e6 / n, err


def parts(rounds):
    """CPU of the lifted run's parts, each alone and in sequence (no threads), medians: the
    source, the fused kernel (in the run's blocks, :data:`daq.benches.BLOCK_S`; also with
    the whole block as one chunk, the kernel of speed round 5), the model information (its
    probe), and whole acquisitions without a sink and with the run file."""
    from daq.acquisition import antialias_for
    from daq.records import RecordPlan

    scene = load_scene(*SCENE)
    acq = scene.acquisition
    plan = RecordPlan.from_acquisition(acq)
    aa = antialias_for(acq, plan)
    model = rb.build_model(scene)
    lifted, sections = rl.lift(model, model.decimation), lift_sections(aa.sos, model.decimation)
    n_all, blk = plan.simulation_samples, int(round(BLOCK_S * plan.simulation_rate_hz))
    whole = "fused kernel, one chunk per block (round 5)"
    out = {k: [] for k in ("source", "fused kernel", whole, "model info", "acquire, no sink",
                           "acquire, run file")}

    def cpu(f):
        c = time.process_time()
        r = f()
        return time.process_time() - c, r

    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(rounds):
            def source():
                st, got = start_source(model.source, 1), []
                for i in range(0, n_all, blk):
                    v, st = generate(model.source, st, min(blk, n_all - i))
                    got.append((v, st))
                return got
            t, got = cpu(source)
            out["source"].append(t)

            def fused():
                st, ch = rb.start(model, 1), rl.start_decimated(aa.sos)
                for v, s in got:
                    s = type(s)(index=st.source.index + v.size, rng_state={}, history=None,
                                buffer=np.empty(0))
                    _, st, ch = rl.advance_decimated(model, lifted, st, ch, v.size, sections,
                                                     (v, s))
            out["fused kernel"].append(cpu(fused)[0])
            chunk, rl.CHUNK_INTERVALS = rl.CHUNK_INTERVALS, n_all  # the same bytes
            out[whole].append(cpu(fused)[0])
            rl.CHUNK_INTERVALS = chunk
            out["model info"].append(cpu(lambda: rb.model_info(scene, seed=1))[0])
            out["acquire, no sink"].append(cpu(lambda: acquire(scene, seed=2009))[0])
            out["acquire, run file"].append(cpu(lambda: acquire(
                scene, seed=2009, sinks=[Hdf5Sink(Path(tmp) / "p.h5", force=True)]))[0])
    print(f"\nparts of the lifted run, CPU [s], medians of {rounds}")
    for k, v in out.items():
        print(f"  {k}: {np.median(v):.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--lsim-s", type=float, default=100.0, help="lsim piece [s] (0: skip)")
    ap.add_argument("--parts", type=int, default=0, help="rounds of the parts' timing (0: skip)")
    args = ap.parse_args(argv)
    if args.parts:
        parts(args.parts)
    if args.rounds < 1:
        return
    names = ["per-sample", "lifted"]
    print(f"load average before: {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as tmp:
        outs = {n: Path(tmp) / f"{n}.h5" for n in names}
        for n in names:
            w, c = one_run(n, outs[n])
            print(f"warm-up {n}: wall {w:.2f} s, CPU {c:.2f} s", flush=True)
        worst, ndiff, dmax, total, flags = compare_files(outs["per-sample"], outs["lifted"])
        walls, cpus = interleaved(names, args.rounds, lambda n: one_run(n, outs[n]),
                                  rotate=False)
    print(f"\n{args.rounds} rounds, interleaved; medians [quartiles]")
    print("| path | CPU per run [s] | wall per run [s] | CPU / per-sample | wall / per-sample | "
          "runs/min on 2 cores |")
    print("|---|---|---|---|---|---|")
    print("\n".join(ratio_rows(names, cpus, walls, digits=3)))
    print(f"\narrays, lifted against per-sample: truth differs by at most {worst:.2g} of a "
          f"series' rms; codes: {ndiff} of {total} samples differ, by at most {dmax} LSB; "
          f"clip and saturation flags {'equal' if flags else 'DIFFER'}")
    if args.lsim_s > 0:
        cpu, cpu_run, err = lsim_peer(args.lsim_s)
        print(f"peer scipy.signal.lsim (ZOH, bench states only) on {args.lsim_s:g} s: CPU "
              f"{cpu:.2f} s, {cpu_run:.1f} s extrapolated to the run; its angles at the kept "
              f"instants differ from the lifted chain's by {err:.2g} of their rms")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
