"""A policy whose metadata's ``residual`` block is bad: ``capsule-export`` says what is wrong
and what is accepted, in one line, and writes nothing."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from conftest import NO_SB3

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR  # noqa: E402

from capsule_env.export.__main__ import main  # noqa: E402


def _policy_with(folder: Path, source: str, residual) -> Path:
    """The shipped policy ``source`` copied as ``p.*`` with its metadata's residual block
    replaced by ``residual``; the ``.zip``."""
    for suffix in (".zip", ".vecnormalize.pkl"):
        shutil.copy(PRETRAINED_DIR / f"{source}{suffix}", folder / f"p{suffix}")
    meta = json.loads((PRETRAINED_DIR / f"{source}.json").read_text()) | {"residual": residual}
    (folder / "p.json").write_text(json.dumps(meta))
    return folder / "p.zip"


@pytest.mark.parametrize(
    ("source", "residual", "expected"),
    [
        # a quarter-car law on the half-car: it is a classical controller, not the half-car's
        ("residual-ppo-mpc-half-car", {"law": "mpc-biexp-meas", "scale": 0.5},
         "not one of the half_car's residual laws (lqr-clipped-biexp-meas, "
         "wheelbase-mpc-biexp-meas)"),
        ("ppo-measured", {"law": "nope", "scale": 0.5}, "accepted: add-meas, "),
        ("ppo-measured", "yes", 'residual must be an object {"law": NAME, "scale": S}'),
    ],
)  # fmt: skip
def test_a_bad_residual_block_is_one_line_naming_what_is_accepted(source, residual, expected,
                                                                  tmp_path, capsys):  # fmt: skip
    zip_path = _policy_with(tmp_path, source, residual)
    assert main([str(zip_path), "--format", "c", "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("capsule-export: error: ")
    assert expected in err, err
    assert not (tmp_path / "out").exists()
