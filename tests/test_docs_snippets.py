"""The code a new user copies from the README and the how-tos runs as written.

Each snippet is extracted from the Markdown as it is published and run as a user would: saved
as a script in a fresh folder (not the repository root, so nothing but the installed package
is importable) and run by a new interpreter. Also: the pages read on GitHub (no Sphinx role
there) and the README's first episode prints the same thing every time.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import NO_SB3

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def python_blocks(path: Path) -> list[str]:
    """The ```python fenced blocks of a Markdown file, in order."""
    return re.findall(r"^```python\n(.*?)^```$", path.read_text(), flags=re.S | re.M)


def run_script(folder: Path, name: str, code: str, timeout_s: float = 300.0) -> str:
    """Write ``code`` to ``folder/name`` and run it there with this interpreter; returns its
    stdout, failing the test with its stderr if it exits non-zero."""
    (folder / name).write_text(code)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    env.pop("PYTHONPATH", None)  # a user's shell: only the installed package
    done = subprocess.run([sys.executable, name], cwd=folder, env=env, capture_output=True,
                          text=True, timeout=timeout_s)  # fmt: skip
    assert done.returncode == 0, f"{name} failed:\n{done.stderr[-3000:]}"
    return done.stdout


def test_readme_first_episode_runs_and_prints_the_same_twice(tmp_path):
    blocks = python_blocks(ROOT / "README.md")
    episode = next(b for b in blocks if "env.step(" in b)
    first = run_script(tmp_path, "first_episode.py", episode)
    second = run_script(tmp_path, "first_episode.py", episode)
    assert re.fullmatch(r"return -?\d+\.\d; last damper force -?\d+ N\n", first), first
    assert first == second  # the env and the random actions are seeded


def test_install_page_shipped_policy_snippet_runs(tmp_path):
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    (snippet,) = python_blocks(DOCS / "install.md")
    run_script(tmp_path, "shipped.py", snippet)


@pytest.mark.slow
def test_howto_own_controller_snippets_run_as_scripts(tmp_path):
    page = DOCS / "howto-own-controller.md"
    law, step2, step3 = python_blocks(page)
    # Steps 2 and 3 import the law from the module step 1 is saved as; the page names it.
    match = re.search(r"^from (\w+) import BodyVelocityLaw$", step2, flags=re.M)
    assert match, "step 2 does not import BodyVelocityLaw: saved as a script it cannot run"
    module = match[1]
    assert f"`{module}.py`" in page.read_text()
    assert f"from {module} import BodyVelocityLaw" in step3
    (tmp_path / f"{module}.py").write_text(law)
    # step 2: Wk (m/s^2), first-mode VRE (%) and max stroke (m) of the law on 10 seeds
    wk, vre, stroke = (float(v) for v in run_script(tmp_path, "step2.py", step2).split())
    assert 0.1 < wk < 1.0 and -100.0 < vre < 100.0 and 0.0 < stroke < 0.06
    # step 3: the law in evaluate.py's tables, in the measured group and in the key
    out = run_script(tmp_path, "step3.py", step3).splitlines()
    table = out[out.index("[measured: only the capsule's own sensors (accelerometers, LVDT, gap, "
                          "coil current) and on-board velocity estimates]") :]  # fmt: skip
    rows = table[1 : next(k for k in range(1, len(table)) if table[k].startswith("["))]
    assert any(row.startswith("my-law ") for row in rows), table[:12]
    assert any(line.startswith("  my-law ") and "[reads: on-board sensors]" in line for line in out)


def test_pages_have_no_sphinx_roles_that_show_raw_on_github():
    # GitHub renders MyST Markdown as plain Markdown: a {py:class}`x` role shows as raw text.
    # Links to the API are written [`x`](#x), which the site resolves and GitHub shows as text.
    for page in sorted(DOCS.glob("*.md")):
        roles = re.findall(r"\{[a-z]+:[a-z]+\}`", page.read_text())
        assert not roles, f"{page.name}: {roles}"
