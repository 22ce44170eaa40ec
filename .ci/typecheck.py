"""Run mypy on the typed part of the checkout: config, envs, agents and evaluation.

The checkout keeps the card layout (``agents/`` at the top) while the code imports it as
``capsule_env.agents`` (``package-dir`` in pyproject.toml). mypy cannot follow the editable
install's import hook, so this script builds the installed layout out of symbolic links in a
temporary folder (``capsule_env/*`` plus ``capsule_env/agents`` -> ``agents/``), runs mypy there
with the checkout's ``[tool.mypy]`` settings, and prints the errors with the checkout's paths.

Usage: ``python .ci/typecheck.py`` from anywhere (exit status: mypy's).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# The files mypy checks, as paths in the installed layout (issue 26 item 7).
TARGETS = (
    "capsule_env/engine/config.py",
    "capsule_env/envs",
    "capsule_env/agents",
    "capsule_env/evaluation/episodes.py",
    "capsule_env/evaluation/evaluate.py",
)


def build_tree(dest: Path) -> None:
    """Mirror the installed package layout in ``dest`` with symbolic links.

    Parameters
    ----------
    dest
        An empty folder; ``dest/capsule_env`` is created in it.
    """
    package = dest / "capsule_env"
    package.mkdir()
    for entry in (ROOT / "capsule_env").iterdir():
        if entry.name != "__pycache__":
            (package / entry.name).symlink_to(entry)
    (package / "agents").symlink_to(ROOT / "agents")


def main() -> int:
    """Run mypy on :data:`TARGETS` and return its exit status."""
    with tempfile.TemporaryDirectory(prefix="capsule-mypy-") as tmp:
        build_tree(Path(tmp))
        command = [
            sys.executable,
            "-m",
            "mypy",
            "--config-file",
            str(ROOT / "pyproject.toml"),
            "--cache-dir",
            str(ROOT / ".mypy_cache"),
            *TARGETS,
        ]
        done = subprocess.run(command, cwd=tmp, capture_output=True, text=True, check=False)
    for stream, text in ((sys.stdout, done.stdout), (sys.stderr, done.stderr)):
        stream.write(text.replace("capsule_env/agents/", "agents/"))
    return done.returncode


if __name__ == "__main__":
    sys.exit(main())
