"""Every "SPEC section N" the tree cites is a section of docs/spec.md, so a clone alone can follow
each citation; and the README, BENCHMARKS.md and docs/ link nothing outside the clone."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "docs" / "spec.md"

#: "SPEC section 5", "SPEC sections 1, 6, 8", "SPEC sections 2-4", "SPEC sections 2 and 8", "SPEC 2"
CITATION = re.compile(r"SPEC(?:\s+sections?)?\s+(\d+(?:\s*(?:,|-|and)\s*\d+)*)")
SOURCES = ("rig", "daq", "processing", "tests", "benchmarks", "docs", "examples")


def _cited_files():
    yield ROOT / "README.md"
    yield ROOT / "tasks.py"
    for top in SOURCES:
        for path in (ROOT / top).rglob("*"):
            if path.suffix in (".py", ".md", ".toml", ".txt") and "__pycache__" not in path.parts:
                yield path


def _sections(spec_text: str) -> set[int]:
    return {int(n) for n in re.findall(r"^## (\d+)\. ", spec_text, re.M)}


def _citations(text: str) -> set[int]:
    out = set()
    for match in CITATION.finditer(text):
        for part in re.split(r"\s*(?:,|and)\s*", match.group(1)):
            lo, _, hi = part.partition("-")
            out.update(range(int(lo), int(hi or lo) + 1))
    return out


def test_citation_pattern_reads_single_listed_ranged_and_short_forms():
    assert _citations("(SPEC section 5)") == {5}
    assert _citations("SPEC sections 1, 6, 8") == {1, 6, 8}
    assert _citations("SPEC sections 2-4 and") == {2, 3, 4}
    assert _citations("SPEC sections 2 and 8") == {2, 8}
    assert _citations("(the chain on a moving base, SPEC 2)") == {2}
    assert _citations("SPEC_KEYS = set()") == set()


def test_every_spec_section_cited_in_the_tree_is_a_section_of_docs_spec():
    sections = _sections(SPEC.read_text(encoding="utf-8"))
    assert sections == set(range(1, 9))
    cited = {}
    for path in _cited_files():
        for n in _citations(path.read_text(encoding="utf-8", errors="replace")):
            cited.setdefault(n, []).append(str(path.relative_to(ROOT)))
    assert len(cited) >= 6, "the pattern should find the code's citations"
    missing = {n: files for n, files in cited.items() if n not in sections}
    assert not missing, f"cited but not in docs/spec.md: {missing}"


def test_readme_docs_and_benchmarks_link_only_inside_the_clone():
    pages = [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").rglob("*.md"))]
    assert "../shared" not in (ROOT / "README.md").read_text(encoding="utf-8")
    checked = 0
    for page in pages:
        text = page.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if re.match(r"[a-z]+://", target):
                continue
            checked += 1
            assert (page.parent / target).resolve().is_relative_to(ROOT), (page, target)
            assert (page.parent / target).exists(), f"{page.relative_to(ROOT)} links {target!r}"
    assert checked > 30
