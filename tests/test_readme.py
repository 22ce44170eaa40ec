"""The README is a front door: short, its two commands the ones CI runs, its headline table at
most ten rows of one fact each, its links alive (issue 40: it had grown to 20.8k characters with
table cells of 1,681 characters)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _section(title: str) -> str:
    match = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", README, flags=re.S | re.M)
    assert match, f"README has no section '## {title}'"
    return match[1]


def _table_rows(text: str) -> list[list[str]]:
    rows = [line for line in text.splitlines() if line.startswith("|")]
    return [[c.strip() for c in row.strip("|").split("|")] for row in rows[2:]]  # no header


def test_readme_reads_in_two_minutes():
    assert len(README) <= 10_000, len(README)
    for title in ("Two commands (fresh machine, Python 3.10+)", "A first episode",
                  "Tasks and reference scores", "Headline figures", "Documentation"):  # fmt: skip
        _section(title)


def test_headline_rows_are_few_and_short():
    rows = _table_rows(_section("Headline figures"))
    assert 1 <= len(rows) <= 10, len(rows)
    for row in rows:
        assert len(row) == 2, row
        assert all(len(cell) <= 200 for cell in row), row


def test_the_two_commands_are_ci_s():
    commands = re.findall(r"^```bash\n(.*?)\n```$", _section(
        "Two commands (fresh machine, Python 3.10+)"), flags=re.S | re.M)  # fmt: skip
    demo, tests = commands
    assert demo.endswith("&& python evaluate.py") and tests.endswith("&& python -m pytest")
    assert demo.rsplit("&&", 1)[0] == tests.rsplit("&&", 1)[0]  # the same set-up
    ci = (ROOT / ".ci" / "run").read_text()
    assert f"\n{tests}\n" in ci, "README's test command is not .ci/run's"


def test_relative_links_point_at_files():
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", README):
        if "://" in target:
            continue
        assert (ROOT / target).exists(), target
