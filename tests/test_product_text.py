"""The repository speaks to its users: no word of how it was developed in its text files (code,
Markdown, YAML), and a README a newcomer reads through."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TEXT = (".py", ".md", ".yaml", ".yml", ".txt", ".toml", ".cfg")
# Development history has its place in git: milestones, tracker numbers, the working sessions and
# machines of the people who wrote the code, the data they tuned on, the days they did it.
PROCESS = re.compile(
    r"\bstops? \d+|\bissues? #?\d+|\b(?:this|that|each|every|one|a|the|later|earlier|next|last|previous)"
    r" (?:work(?:ing)? )?sessions?\b|\bsession of\b|\bthis machine\b|\bdevelopment machine\b"
    r"|\btuning set\b|\b20\d\d-[01]\d-[0-3]\d\b", re.IGNORECASE)


def _text_files() -> list[Path]:
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"],
                            cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    return [ROOT / f for f in listed
            if (f.endswith(TEXT) or Path(f).name == "Makefile") and f != "tests/test_product_text.py"
            and (ROOT / f).is_file()]


def test_no_word_of_how_the_project_was_developed():
    found = [f"{p.relative_to(ROOT)}:{n}: {m.group(0)}" for p in _text_files()
             for n, line in enumerate(p.read_text(errors="replace").splitlines(), 1)
             for m in [PROCESS.search(line)] if m]
    assert found == [], f"{len(found)} lines speak of the development:\n" + "\n".join(found[:60])


@pytest.mark.parametrize("line, hit", [
    ("since stop 44 urban.yaml parks no cars", True), ("issue 16's 90 holds", True),
    ("the 2-core development machine", True), ("measured in an earlier session", True),
    ("frozen on 2026-11-28", True), ("not on the tuning set", True),
    ("@pytest.fixture(scope=\"session\")", False), ("a stop sign", False), ("2011_09_26_drive_0001", False),
])
def test_the_process_words_are_told_from_ordinary_ones(line, hit):
    assert bool(PROCESS.search(line)) is hit


def test_readme_is_at_most_200_lines():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200
