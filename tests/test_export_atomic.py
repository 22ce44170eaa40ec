"""Exporting into a folder that already holds an export: all the files are replaced, or none."""

from __future__ import annotations

import hashlib

import pytest

from conftest import NO_SB3

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from capsule_env.export.__main__ import main  # noqa: E402


def _digests(folder) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.iterdir()) if p.is_file()}  # fmt: skip


def test_a_target_taken_by_a_folder_leaves_the_earlier_export_whole(tmp_path, capsys):
    """The export's files are renamed onto their names one by one: a name taken by a folder
    (here NAME.h) failed its rename after NAME.onnx and NAME.c had been replaced, leaving another
    policy's files beside the earlier contract. It is refused before anything is replaced."""
    out = tmp_path / "out"
    assert main(["ppo-measured", "--format", "onnx,c", "--out", str(out), "--name", "p"]) == 0
    (out / "p.h").unlink()
    (out / "p.h").mkdir()
    before = _digests(out)
    capsys.readouterr()
    assert main(["ppo-trip", "--format", "onnx,c", "--out", str(out), "--name", "p"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "p.h" in err and "not a file" in err, err
    assert _digests(out) == before
    assert sorted(p.name for p in out.iterdir()) == ["p.c", "p.contract.json", "p.h", "p.onnx"]
