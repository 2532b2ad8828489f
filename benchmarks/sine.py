#!/usr/bin/env python3
"""The stepped-sine sweep's cost as simulated bench time over CPU time, beside the FFT
acquisition's own ratio in the same process, and its accuracy at every point.

    .venv/bin/python benchmarks/sine.py                       # 3 rounds (~5 minutes loaded)
    .venv/bin/python benchmarks/sine.py --rounds 1 --figure docs/figures/sine-vs-fft.png
    .venv/bin/python benchmarks/sine.py --swept --rounds 3   # stepped, swept and FFT

Per round, in alternating order: (A) the accuracy sweep of the README and of
tests/processing/test_sine.py over 0.1-10 Hz on ``ishizaki2009`` (auto resolution 2 dB / 20
deg from a 50-point log grid, the mirror's rotation held at 3e-4 rad by auto level up to 1 V,
windows continued to a 0.02 dB random error up to 20,000 s, the settle rule from the poles),
in memory; (B) the paper's FFT acquisition (30 x 100 s at 100 Hz after 300 s settling, seed
2009) into a MemorySink. Each one's ratio is its simulated bench seconds (every point's settle
and window, discarded points included; the FFT run's settle and records) over its CPU seconds
(``time.process_time``, every thread of the process, the sine sweep's model choice and exact
truth included). One warm-up of each first (numba's cache, the filter design). Printed: each
round's two ratios and their quotient, the sweep's points, and its largest differences from
the exact response against the 0.1 dB / 0.5 deg of the issue. ``--figure`` draws the FFT
measurement (``daq analyze``'s default Hann analysis of run B) and the sweep of the last round
over the exact model, side by side (README "Swept and stepped sine"). ``--swept`` times the
swept sine (``mode="swept"``, 200 points, the rule's path at its default tolerance) beside the
stepped sweep and the FFT run, the order rotating per round, and prints both sweeps' accuracy.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import rig  # noqa: E402
from daq.acquisition import acquire  # noqa: E402
from daq.sinks import MemorySink  # noqa: E402
from processing.sine_sweep import SineSettings, measure_sine  # noqa: E402

ACCURACY = SineSettings(fmin_hz=0.1, fmax_hz=10.0, points=50, auto_resolution=(2.0, 20.0),
                        auto_level=("y", 3e-4, 0.2), level_limit_vrms=1.0,
                        random_error_db=0.02, max_integrate_s=20000.0)
#: the swept sine of ``daq sine --mode swept`` (200 points, the rule's path at its default
#: tolerance, the auto level a profile along the sweep)
SWEPT = SineSettings(fmin_hz=0.1, fmax_hz=10.0, points=200, auto_level=("y", 3e-4, 0.2),
                     level_limit_vrms=1.0, mode="swept")


def sine_run(scene, settings, seed):
    t = time.process_time()
    sweep = measure_sine(scene, settings, seed)
    cpu = time.process_time() - t
    return sweep.bench_s, cpu, sweep


def fft_run(scene, seed):
    mem = MemorySink()
    t = time.process_time()
    acquire(scene, seed=seed, sinks=[mem])
    cpu = time.process_time() - t
    acq = scene.acquisition
    return acq.settle_s + acq.records * acq.record_s, cpu, mem.recording


def accuracy_lines(sweep) -> list[str]:
    out = []
    for name, what in (("h_t", "H_t"), ("theta_2", "Theta_2")):
        d = np.array([p.gain_phase_error(name) for p in sweep.points])
        b = np.array([p.bias_db_deg(name) for p in sweep.points])
        e = np.array([p.error_db_deg(name) for p in sweep.points])
        i = int(np.argmax(np.abs(d[:, 0])))
        j = int(np.argmax(np.abs(d[:, 1])))
        out.append(f"  {what}: max |measured - exact| {abs(d[i, 0]):.4f} dB (at "
                   f"{sweep.points[i].frequency_hz:.4f} Hz), {abs(d[j, 1]):.3f} deg (at "
                   f"{sweep.points[j].frequency_hz:.4f} Hz); max |stated bias| "
                   f"{np.max(np.abs(b[:, 0])):.4f} dB, {np.max(np.abs(b[:, 1])):.3f} deg; max "
                   f"random error {np.max(e[:, 0]):.4f} dB; within 0.1 dB and 0.5 deg at "
                   f"{int(np.sum((np.abs(d[:, 0]) <= 0.1) & (np.abs(d[:, 1]) <= 0.5)))} of "
                   f"{len(d)} points")
    return out


def figure(path, scene, sweep, recording):
    """The FFT measurement and the sweep over the exact model (the README's figure)."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter, NullFormatter

    import processing
    from processing.plots import phase_curve
    from processing.sine import DB

    a = processing.analyze(recording)
    m = a.display
    f_fft = a.freqs_hz[m]
    fm = np.unique(np.concatenate([np.geomspace(0.1, 10, 3000),
                                   np.linspace(2.45, 2.51, 1201), np.linspace(0.80, 0.85, 501),
                                   np.linspace(4.60, 4.72, 601)]))
    model = rig.expected_response(scene, fm, sampled=True)
    f_s = sweep.column("frequency_hz")
    fig = Figure(figsize=(12, 10.5), layout="constrained")
    zooms = {"h_t": (2.455, 2.505), "theta_2": (4.58, 4.74)}
    for col, (name, what, unit) in enumerate((("h_t", "H_t", "m/(m/s^2)"),
                                              ("theta_2", "Theta_2", "rad/(m/s^2)"))):
        ax_g = fig.add_subplot(3, 2, col + 1)
        ax_p = fig.add_subplot(3, 2, col + 3, sharex=ax_g)
        ax_z = fig.add_subplot(3, 2, col + 5)
        hm = getattr(model, name)
        hf = getattr(a, name).h[m]
        hs = np.array([getattr(p, name) for p in sweep.points])
        for ax in (ax_g, ax_z):
            ax.plot(fm, DB * np.log(np.abs(hm)), color="0.25", lw=1.0,
                    label="exact model of the whole chain")
            ax.plot(f_fft, DB * np.log(np.abs(hf)), ".-", ms=3, color="tab:blue", lw=0.8,
                    alpha=0.8, label="FFT: 30 x 100 s random noise, Hann, H1 "
                                     "(3300 s of bench time)")
            ax.plot(f_s, DB * np.log(np.abs(hs)), "o", ms=2.4, color="tab:red",
                    label=f"stepped sine: {len(f_s)} points "
                          f"({sweep.bench_s / 3600:.0f} h of bench time)")
        ax_g.set_xscale("log")
        ax_p.semilogx(*phase_curve(fm, hm), color="0.25", lw=1.0)
        ax_p.semilogx(*phase_curve(f_fft, hf), color="tab:blue", lw=0.8, alpha=0.8)
        ax_p.semilogx(f_s, np.degrees(np.angle(hs)), "o", ms=2.4, color="tab:red")
        lo, hi = zooms[name]
        ax_z.set_xlim(lo, hi)
        inside = (fm >= lo) & (fm <= hi)
        g = DB * np.log(np.abs(hm[inside]))
        ax_z.set_ylim(g.min() - 8, g.max() + 5)
        ax_z.set_title(f"{what} near the {'2.48 Hz mode' if name == 'h_t' else '4.66 Hz notch'}"
                       " (linear frequency axis)", fontsize=10)
        ax_z.set_ylabel(f"gain |{what}| [dB]")
        ax_z.set_xlabel("frequency [Hz]")
        ax_z.grid(True, alpha=0.3)
        ax_g.set_title(f"{what} per stage acceleration")
        ax_g.set_ylabel(f"gain |{what}| [dB re 1 {unit}]")
        ax_p.set_ylabel(f"phase of {what} [deg]")
        ax_p.set_ylim(-190, 190)
        ax_p.set_yticks([-180, -90, 0, 90, 180])
        ax_p.set_xlabel("frequency [Hz]")
        for ax in (ax_g, ax_p):
            ax.grid(True, which="both", alpha=0.3)
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            ax.xaxis.set_minor_formatter(NullFormatter())
        ax_g.set_xlim(0.1, 10)
        if col == 0:
            h_, l_ = ax_g.get_legend_handles_labels()
            fig.legend(h_, l_, loc="outside lower center", ncols=3, fontsize=8, frameon=False)
    fig.suptitle("ishizaki2009: the FFT measurement and the stepped sine of the same bench")
    fig.savefig(path, dpi=110)


def swept_rounds(rounds: int) -> None:
    """Stepped (A), swept (S) and FFT (B) side by side, the order rotating per round."""
    scene = rig.load_scene("ishizaki2009")
    warm = SineSettings(fmin_hz=2.0, fmax_hz=3.0, points=3, auto_level=("y", 3e-4, 0.2))
    sine_run(scene, warm, 1)
    sine_run(scene, SineSettings(fmin_hz=1.0, fmax_hz=1.2, points=3, mode="swept",
                                 sweep_tolerance=0.05, level_vrms=0.05), 1)
    fft_run(scene.with_acquisition(records=2), 1)
    kinds = ("stepped", "swept", "fft")
    rows, last = [], {}
    for r in range(rounds):
        order = kinds[r % 3:] + kinds[:r % 3]
        got = {}
        for which in order:
            got[which] = (fft_run(scene, 2009) if which == "fft" else
                          sine_run(scene, ACCURACY if which == "stepped" else SWEPT, 2009))
            last[which] = got[which][2]
        ratio = {k: got[k][0] / got[k][1] for k in kinds}
        rows.append(ratio)
        print(f"round {r + 1} ({' then '.join(order)}): " + "; ".join(
            f"{k} {got[k][0]:,.0f} s bench / {got[k][1]:.2f} s CPU = {ratio[k]:,.0f} x"
            for k in kinds) + f"; swept / stepped {ratio['swept'] / ratio['stepped']:.2f}",
            flush=True)
    med = {k: float(np.median([row[k] for row in rows])) for k in kinds}
    print(f"median over {rounds} rounds: " + ", ".join(f"{k} {v:,.0f} x" for k, v in med.items())
          + f"; swept / stepped {np.median([r['swept'] / r['stepped'] for r in rows]):.2f}")
    for k in ("stepped", "swept"):
        sw = last[k]
        print(f"{k}: {len(sw.points)} points, {sw.bench_s:,.0f} s of bench time, "
              f"{sw.model_info['model']} model; against the exact response:")
        print("\n".join(accuracy_lines(sw)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--figure", type=Path, default=None)
    ap.add_argument("--figure-only", action="store_true",
                    help="One sweep and one FFT run for --figure, nothing timed.")
    ap.add_argument("--swept", action="store_true",
                    help="Time the stepped sweep, the swept sweep and the FFT run side by "
                         "side (the order rotating per round).")
    args = ap.parse_args()
    if args.swept:
        swept_rounds(args.rounds)
        return
    scene = rig.load_scene("ishizaki2009")
    if args.figure_only:
        sweep = sine_run(scene, ACCURACY, 2009)[2]
        figure(args.figure, scene, sweep, fft_run(scene, 2009)[2])
        print("\n".join(accuracy_lines(sweep)))
        print(f"wrote {args.figure}")
        return
    warm = SineSettings(fmin_hz=2.0, fmax_hz=3.0, points=3, auto_level=("y", 3e-4, 0.2))
    sine_run(scene, warm, 1)
    fft_run(scene.with_acquisition(records=2), 1)
    rows = []
    for r in range(args.rounds):
        order = ("sine", "fft") if r % 2 == 0 else ("fft", "sine")
        got = {}
        for which in order:
            got[which] = (sine_run(scene, ACCURACY, 2009) if which == "sine"
                          else fft_run(scene, 2009))
        (sb, sc, sweep), (fb, fc, rec) = got["sine"], got["fft"]
        rows.append((sb / sc, fb / fc))
        print(f"round {r + 1} ({' then '.join(order)}): sine {sb:,.0f} s bench / {sc:.2f} s CPU "
              f"= {sb / sc:,.0f} x ({len(sweep.points)} points, {len(sweep.discarded)} "
              f"discarded, {sweep.model_info['model']} model); FFT {fb:,.0f} s / {fc:.2f} s = "
              f"{fb / fc:,.0f} x; sine / FFT {sb / sc / (fb / fc):.2f}", flush=True)
    ratios = np.array(rows)
    print(f"median over {len(rows)} rounds: sine {np.median(ratios[:, 0]):,.0f} x, FFT "
          f"{np.median(ratios[:, 1]):,.0f} x, sine / FFT "
          f"{np.median(ratios[:, 0] / ratios[:, 1]):.2f}")
    print("accuracy of the last sweep against the exact response:")
    print("\n".join(accuracy_lines(sweep)))
    if args.figure is not None:
        figure(args.figure, scene, sweep, rec)
        print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
