"""Interleaved timing shared by the benchmark scripts: runs alternated so that each comparison is
made under the same load, medians and quartiles of the times and of the per-round ratios."""

from __future__ import annotations

import numpy as np


def quart(x):
    """(first quartile, median, third quartile) of ``x``."""
    return np.percentile(x, 25), np.median(x), np.percentile(x, 75)


def interleaved(names: list, rounds: int, run, *, rotate: bool = True) -> tuple[dict, dict]:
    """``run(name) -> (wall, cpu, ...)`` for every name in every round, in a rotating order (A B
    C, B C A, ...; or alternating A B, B A with ``rotate=False``). Returns (walls, cpus): name ->
    list of seconds, one per round."""
    walls = {n: [] for n in names}
    cpus = {n: [] for n in names}
    for r in range(rounds):
        if rotate:
            order = names[r % len(names):] + names[:r % len(names)]
        else:
            order = names if r % 2 == 0 else names[::-1]
        for n in order:
            w, c = run(n)[:2]
            walls[n].append(w)
            cpus[n].append(c)
    return walls, cpus


def ratio_rows(names: list, cpus: dict, walls: dict, *, digits: int = 2) -> list[str]:
    """Markdown rows ``| name | CPU [q] | wall [q] | CPU / first | wall / first | runs/min |``
    (runs per minute on 2 cores: 2 x 60 s / median CPU), ratios per round to the first name."""
    c0, w0 = np.array(cpus[names[0]]), np.array(walls[names[0]])
    f = f".{digits}f"
    rows = []
    for n in names:
        c, w = np.array(cpus[n]), np.array(walls[n])
        qc, qw, rc, rw = quart(c), quart(w), quart(c / c0), quart(w / w0)
        rows.append(f"| {n} | {qc[1]:{f}} [{qc[0]:{f}}, {qc[2]:{f}}] | {qw[1]:{f}} [{qw[0]:{f}}, "
                    f"{qw[2]:{f}}] | {rc[1]:{f}} [{rc[0]:{f}}, {rc[2]:{f}}] | {rw[1]:{f}} "
                    f"[{rw[0]:{f}}, {rw[2]:{f}}] | {120 / qc[1]:.0f} |")
    return rows


def tree_pairs(trees: dict, pairs: int, run, report=None) -> dict:
    """``run(tree_path)`` for the trees "this" and "baseline" in turn, the order swapped every
    pair (A B, B A, ...); ``report(pair, name, result)`` after each. Returns name -> results."""
    res = {k: [] for k in trees}
    for p in range(pairs):
        order = ["this", "baseline"] if p % 2 == 0 else ["baseline", "this"]
        for k in order:
            res[k].append(run(trees[k]))
            if report is not None:
                report(p, k, res[k][-1])
    return res
