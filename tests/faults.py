"""The reliability tests' own record: faults injected, bad inputs tried, records lost, readers
that opened the files. Tests call :func:`record_fault`, :func:`record_inputs` and
:func:`record_readers`; at the end of a test session ``tests/conftest.py`` writes what was
recorded to ``out/reliability.json`` (merged with an earlier run's entries, so a partial run
updates only what it ran), and ``python tests/faults.py`` prints it as the README's
"Reliability" table (Markdown)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REPORT = ROOT / "out" / "reliability.json"
_faults: dict[str, dict] = {}
_inputs: dict[str, int] = {}
_readers: set[str] = set()


def record_fault(fault: str, *, records_lost: int, outcome: str) -> None:
    """A fault injected into a real CLI run: ``records_lost`` finished records not readable
    afterwards, ``outcome`` what the user saw."""
    _faults[fault] = {"records_lost": int(records_lost), "outcome": outcome}


def record_inputs(kind: str, count: int) -> None:
    """``count`` inputs of ``kind`` tried (added up over a session)."""
    _inputs[kind] = _inputs.get(kind, 0) + int(count)


def record_readers(reader: str) -> None:
    """A reader that opened every object of every file the project writes."""
    _readers.add(reader)


def write_report(path: Path = REPORT) -> None:
    if not (_faults or _inputs or _readers):
        return
    old = json.loads(path.read_text()) if path.exists() else {}
    report = {"faults": {**old.get("faults", {}), **_faults},
              "inputs": {**old.get("inputs", {}), **_inputs},
              "readers": sorted(set(old.get("readers", [])) | _readers)}
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(report, indent=2, sort_keys=True) + "\n")


def table(report: dict) -> str:
    lines = ["| fault injected | what the user sees | records lost |", "|---|---|---|"]
    for k, v in sorted(report.get("faults", {}).items()):
        lines.append(f"| {k} | {v['outcome']} | {v['records_lost']} |")
    lines += ["", "| inputs tried, valid and invalid (hypothesis, fixed grids, CLI cases) | count |",
              "|---|---|"]
    for k, v in sorted(report.get("inputs", {}).items()):
        lines.append(f"| {k} | {v} |")
    lines += ["", "Readers that open every object and attribute of the run, spectra and "
                  "trajectory files: " + ", ".join(report.get("readers", [])) + "."]
    return "\n".join(lines)


if __name__ == "__main__":
    p = Path(sys.argv[1]) if len(sys.argv) > 1 else REPORT
    print(table(json.loads(p.read_text())))
