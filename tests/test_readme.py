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


def test_index_layout_names_only_what_exists():
    # the site's layout listing named a dampers.py that had become the dampers/ package
    index = (ROOT / "docs" / "index.md").read_text()
    block = re.search(r"## Layout\n.*?^```\n(.*?)^```", index, flags=re.S | re.M)[1]
    folder = ROOT
    for line in block.splitlines():
        if not line[:1].isspace():  # a top-level entry: "capsule_env/", "agents/", ...
            folder = ROOT
        names = re.findall(r"(?:^|\s)([\w.]+/|[\w]+\.py)(?=\s|,|$)", line[:25])
        for name in names:
            where = folder / name if line[:1].isspace() else ROOT / name
            assert where.exists(), f"docs/index.md's layout names {name}, absent from {folder}"
        top = re.match(r"([\w.]+)/", line)
        if top:  # a top-level folder: the indented names below it are in it
            folder = ROOT / top.group(1)


def test_howto_train_counts_the_shipped_policies():
    # it said "Five policies ship" over a table of six
    words = {4: "Four", 5: "Five", 6: "Six", 7: "Seven", 8: "Eight", 9: "Nine", 10: "Ten"}
    shipped = sorted((ROOT / "capsule_env" / "pretrained").glob("*.json"))
    page = (ROOT / "docs" / "howto-train.md").read_text()
    assert f"{words[len(shipped)]} policies ship in `capsule_env/pretrained/`" in page
    for meta in shipped:
        assert f"| `{meta.stem}` |" in page, meta.stem
