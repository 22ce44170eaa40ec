"""The scripts (train.py, evaluate.py, python -m capsule_env.identification.cli) under bad input, kills
and full disks: one line on stderr and a non-zero exit for bad input, checked before any run;
saves that leave the previous files intact; resumable checkpoints.

Kills are simulated by an exception no handler catches (raised from a training callback), a
full disk by a write that stores half its data and then raises ``OSError(ENOSPC)``, corrupt
files by random bytes.

The cases of SB3 policies and of train.py need the optional rl extra (``rl`` marker; skipped,
with the reason, without it); those of safe_io, identify and evaluate.py's other arguments
do not.
"""

from __future__ import annotations

import builtins
import errno
import io
import json
import os
import shutil
import stat
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from capsule_env.agents.learning.checkpoints import (
    checkpoint_problem,
    latest_checkpoint,
    save_policy,
    saved_at,
)
from capsule_env.agents.learning.sb3_policy import SB3Policy
from scipy import io as sio

from capsule_env.common.safe_io import StagedFiles, atomic_write_text, check_writable_file
from capsule_env.evaluation import evaluate
from capsule_env.identification import cli as identify

from conftest import NO_SB3, NO_YAML

ROOT = Path(__file__).resolve().parent.parent
POLICY_ENV = {"setting": "hils", "action_mode": "force", "observation": "full_state"}
# evaluate.py: one classical controller, one short episode, one setting
QUICK_EVAL = ["--controllers", "passive", "--episodes", "1", "--episode-length", "0.5",
              "--setting", "sim", "--no-shipped-policy"]  # fmt: skip


# ------------------------------------------------------------------------------- helpers
@pytest.fixture(scope="module")
def train():
    """The train.py module (it imports torch and stable-baselines3, and reads PyYAML files)."""
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    pytest.importorskip("yaml", reason=NO_YAML)
    from capsule_env.agents.learning import train as module

    return module


def exit_of(main: Callable[[list[str]], Any], argv: list[str], capsys) -> tuple[int, str]:
    """Run a script's ``main`` in-process: its exit status and what it wrote to stderr (with
    the message of a ``SystemExit("...")``, which Python prints there)."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    if isinstance(code, str):
        err += code + "\n"
        code = 1
    return int(code or 0), err


def assert_one_line_error(code: int, err: str, *expected: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert code != 0
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for text in expected:
        assert text in lines[0], (text, lines[0])


def make_policy(stem: Path, name: str | None = "tiny", env: str = "capsule") -> Any:
    """Save an untrained PPO policy as train.py does (``stem.zip``, ``.vecnormalize.pkl``,
    ``.json``); ``env="pendulum"``: one trained on 3-dimensional observations. Returns the
    model. Skips the calling test without stable-baselines3."""
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    from capsule_env.agents.learning.training import make_env
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    if env == "pendulum":
        import gymnasium as gym

        venv = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]))
    else:
        venv = make_env(2, 0, POLICY_ENV, {"norm_obs": True, "norm_reward": True})
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, seed=0, device="cpu")
    meta = {"algo": "ppo", "env_kwargs": POLICY_ENV, "num_timesteps": 0}
    if name is not None:
        meta["name"] = name
    save_policy(model, stem, meta)
    return model


def files_of(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


class _HalfWriter:
    """A file whose writes store half their data, then fail as on a full disk."""

    def __init__(self, fh: Any) -> None:
        self._fh = fh

    def write(self, data: Any) -> int:
        self._fh.write(data[: len(data) // 2])
        self._fh.flush()
        raise OSError(errno.ENOSPC, "No space left on device")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._fh, name)

    def __enter__(self) -> _HalfWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self._fh.close()


@pytest.fixture
def full_disk(monkeypatch):
    """``full_disk(folder)``: from now on every file opened for writing under ``folder``
    (through ``open``, ``io.open`` or ``pathlib``) is on a full disk."""

    def install(folder: Path) -> None:
        real_open = io.open
        folder = Path(folder).resolve()

        def fake_open(file, mode="r", *args, **kwargs):
            fh = real_open(file, mode, *args, **kwargs)
            inside = isinstance(file, (str, Path)) and folder in Path(file).resolve().parents
            return _HalfWriter(fh) if inside and any(c in mode for c in "wax+") else fh

        monkeypatch.setattr(builtins, "open", fake_open)
        monkeypatch.setattr(io, "open", fake_open)

    return install


# --------------------------------------------------------------------- atomic writes (12)
def test_staged_files_replace_together_or_not_at_all(tmp_path):
    a, b = tmp_path / "a.bin", tmp_path / "b.json"
    a.write_bytes(b"old a")
    b.write_text("old b")
    with pytest.raises(RuntimeError), StagedFiles() as staged:
        staged.write_bytes(a, b"new a")
        raise RuntimeError("killed between the two writes")
    assert files_of(tmp_path) == {"a.bin": b"old a", "b.json": b"old b"}  # no temp left
    with StagedFiles() as staged:
        staged.write_bytes(a, b"new a")
        staged.write_text(b, "new b")
    assert files_of(tmp_path) == {"a.bin": b"new a", "b.json": b"new b"}


def test_atomic_write_on_a_full_disk_keeps_the_old_file(tmp_path, full_disk):
    target = tmp_path / "out.json"
    target.write_text('{"previous": true}')
    full_disk(tmp_path)
    with pytest.raises(OSError, match="No space"):
        atomic_write_text(target, json.dumps({"new": list(range(1000))}))
    assert files_of(tmp_path) == {"out.json": b'{"previous": true}'}


def test_a_pipe_a_folder_or_nothing_is_refused_as_an_output_file(tmp_path):
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    with pytest.raises(ValueError, match="--json .*pipe.* is not a regular file"):
        check_writable_file(pipe, "--json")
    assert stat.S_ISFIFO(pipe.stat().st_mode)  # left as it was
    with pytest.raises(ValueError, match="--out .* is a folder"):
        check_writable_file(tmp_path, "--out")
    with pytest.raises(ValueError, match="--json is empty"):
        check_writable_file("", "--json")
    assert check_writable_file(tmp_path / "new" / "out.json", "--json").parent.is_dir()


@pytest.mark.rl
@pytest.mark.parametrize("failing", ["model", "statistics"])
def test_failed_policy_save_leaves_the_previous_files_intact(tmp_path, monkeypatch, failing):
    vec_env = pytest.importorskip("stable_baselines3.common.vec_env", reason=NO_SB3)
    stem = tmp_path / "best_model"
    model = make_policy(stem)
    before = files_of(tmp_path)
    assert set(before) == {"best_model.zip", "best_model.vecnormalize.pkl", "best_model.json"}
    model.num_timesteps = 4096  # a newer model: its files would differ

    def half_then_full(path: Any, *args: Any, **kwargs: Any) -> None:
        Path(path).write_bytes(b"PK\x03\x04 half a file")
        raise OSError(errno.ENOSPC, "No space left on device")

    cls = type(model) if failing == "model" else vec_env.VecNormalize
    monkeypatch.setattr(cls, "save", lambda self, path, *a, **k: half_then_full(path))
    with pytest.raises(OSError, match="No space"):
        save_policy(model, stem, {"algo": "ppo", "name": "tiny", "num_timesteps": 4096})
    assert files_of(tmp_path) == before  # unchanged, and no temporary file left behind
    SB3Policy.load(stem.with_suffix(".zip"))


@pytest.mark.rl
def test_loader_refuses_a_model_mixed_with_another_saves_statistics(tmp_path):
    make_policy(tmp_path / "a" / "best_model")
    other = make_policy(tmp_path / "b" / "best_model", name="other")
    other.num_timesteps = 77
    save_policy(other, tmp_path / "b" / "best_model", {"algo": "ppo", "name": "other"})
    # the zip of one save next to the statistics and json of another
    shutil.copy(tmp_path / "b" / "best_model.zip", tmp_path / "a" / "best_model.zip")
    with pytest.raises(ValueError, match="best_model.zip") as info:
        SB3Policy.load(tmp_path / "a" / "best_model.zip")
    assert "does not match" in str(info.value)
    SB3Policy.load(tmp_path / "b" / "best_model.zip")  # the consistent set loads


def test_evaluate_json_on_a_full_disk_keeps_the_previous_file(tmp_path, full_disk, capsys):
    out = tmp_path / "eval.json"
    out.write_text('{"previous": true}')
    full_disk(tmp_path)
    code, err = exit_of(evaluate.main, [*QUICK_EVAL, "--json", str(out)], capsys)
    # after the run (its progress bar above): the error is the last line
    assert code != 0 and "Traceback" not in err
    assert "eval.json" in err.splitlines()[-1] and "No space" in err.splitlines()[-1]
    assert files_of(tmp_path) == {"eval.json": b'{"previous": true}'}


# --------------------------------------------------------------------- evaluate.py (6, 15)
@pytest.mark.rl
def test_policies_with_the_same_name_get_distinct_rows(tmp_path, capsys):
    a = tmp_path / "runs" / "a" / "best_model"
    b = tmp_path / "runs" / "b" / "best_model"
    make_policy(a, name=None)  # no name in the json: the file stem, best_model
    make_policy(b, name=None)
    out = tmp_path / "eval.json"
    argv = [*QUICK_EVAL, "--json", str(out)]
    for path in (a, b, a):  # the same file twice, and another with the same stem
        argv += ["--policy", str(path) + ".zip"]
    assert evaluate.main(argv) == 0
    data = json.loads(out.read_text())
    rows = data["settings"]["sim"]["controllers"]
    assert set(rows) == {"passive", "best_model", "best_model#2", "best_model#3"}
    assert data["policies"] == {
        "best_model": str(a) + ".zip",
        "best_model#2": str(b) + ".zip",
        "best_model#3": str(a) + ".zip",
    }
    assert "best_model#2 = " + str(b) + ".zip" in capsys.readouterr().out
    # a policy whose name is a classical controller's does not replace that controller
    passive_named = tmp_path / "c" / "best_model"
    make_policy(passive_named, name="passive")
    assert evaluate.main([*QUICK_EVAL, "--json", str(out), "--policy",
                          str(passive_named) + ".zip"]) == 0  # fmt: skip
    rows = json.loads(out.read_text())["settings"]["sim"]["controllers"]
    assert set(rows) == {"passive", "passive#2"}
    assert "uses_unmeasured_signals" in rows["passive"] and rows["passive#2"]["vre_pct"]


@pytest.mark.rl
def test_policy_without_statistics_is_refused_unless_allowed(tmp_path, capsys):
    stem = tmp_path / "best_model"
    make_policy(stem)
    Path(str(stem) + ".vecnormalize.pkl").unlink()
    with pytest.raises(ValueError, match="vecnormalize.pkl"):
        SB3Policy.load(str(stem) + ".zip")
    assert SB3Policy.load(str(stem) + ".zip", require_normalization=False).obs_rms is None
    argv = [*QUICK_EVAL, "--policy", str(stem) + ".zip"]
    code, err = exit_of(evaluate.main, argv, capsys)
    assert_one_line_error(code, err, "best_model.zip", "--allow-unnormalized")
    out = tmp_path / "eval.json"
    assert evaluate.main([*argv, "--allow-unnormalized", "--json", str(out)]) == 0
    assert "tiny" in json.loads(out.read_text())["settings"]["sim"]["controllers"]
    assert "raw observations" in capsys.readouterr().err


@pytest.fixture
def no_run(monkeypatch):
    """Fail the test if evaluate.py starts running episodes."""

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("the run started before the arguments were checked")

    monkeypatch.setattr(evaluate, "run_episodes", refuse)


def _bad_evaluate_case(case: str, tmp: Path) -> tuple[list[str], list[str]]:
    """``(argv, texts the one-line message must hold)`` of a bad evaluate.py invocation."""
    made = _bad_policy_case(case, tmp) or _bad_option_case(case, tmp)
    if made is None:
        raise KeyError(case)
    return made


def _bad_policy_case(case: str, tmp: Path) -> tuple[list[str], list[str]] | None:
    """A bad ``--policy`` file (None: ``case`` is not one of these)."""
    if case == "missing policy":
        return ["--policy", str(tmp / "nope.zip")], ["nope.zip"]
    if case == "corrupt policy":
        pytest.importorskip("stable_baselines3", reason=NO_SB3)  # SB3 reads the zip
        path = tmp / "corrupt.zip"
        path.write_bytes(np.random.default_rng(0).bytes(4096))
        shutil.copy(ROOT / "capsule_env/pretrained/ppo-hils.vecnormalize.pkl",
                    tmp / "corrupt.vecnormalize.pkl")  # fmt: skip
        return ["--policy", str(path)], ["corrupt.zip", "cannot load"]
    if case == "empty policy":
        (tmp / "empty.zip").write_bytes(b"")
        return ["--policy", str(tmp / "empty.zip")], ["empty.zip", "empty"]
    if case == "corrupt statistics":
        make_policy(tmp / "p")
        (tmp / "p.vecnormalize.pkl").write_bytes(b"\x80\x04garbage")
        (tmp / "p.json").write_text(json.dumps({"algo": "ppo", "env_kwargs": POLICY_ENV}))
        return ["--policy", str(tmp / "p.zip")], ["p.vecnormalize.pkl"]
    if case == "other observation size":
        make_policy(tmp / "pendulum", name="pendulum", env="pendulum")
        return ["--policy", str(tmp / "pendulum.zip")], ["pendulum.zip", "(3,)", "(10,)"]
    return None


def _bad_option_case(case: str, tmp: Path) -> tuple[list[str], list[str]] | None:
    """A bad value of another option (None: ``case`` is not one of these)."""
    if case == "negative seed":
        return ["--seed", "-1"], ["--seed"]
    if case == "zero episodes":
        return ["--episodes", "0"], ["--episodes"]
    if case == "shorter than a control step":
        return ["--episode-length", "0.001"], ["--episode-length", "control step", "0.335 s"]
    if case == "too short for the spectra":
        return ["--episode-length", "0.2"], ["--episode-length", "at least 0.335 s"]
    if case == "json is a folder":
        return ["--json", str(tmp)], ["--json", "is a folder"]
    if case == "json in a non-folder":
        (tmp / "file").write_text("x")
        return ["--json", str(tmp / "file" / "out.json")], ["--json", "is a file, not a folder"]
    if case == "plots is a file":
        (tmp / "file").write_text("x")
        return ["--plots", str(tmp / "file")], ["--plots", "is a file"]
    return None


NEEDS_SB3 = ["corrupt policy", "corrupt statistics", "other observation size"]
BAD_EVALUATE = [pytest.param(case, marks=pytest.mark.rl) if case in NEEDS_SB3 else case
                for case in ["missing policy", "corrupt policy", "empty policy",
                             "corrupt statistics", "other observation size", "negative seed",
                             "zero episodes", "shorter than a control step",
                             "too short for the spectra", "json is a folder",
                             "json in a non-folder", "plots is a file"]]  # fmt: skip


@pytest.mark.parametrize("case", BAD_EVALUATE)
def test_evaluate_bad_input_is_one_line_before_the_run(case, tmp_path, capsys, no_run):
    argv, expected = _bad_evaluate_case(case, tmp_path)
    code, err = exit_of(evaluate.main, [*QUICK_EVAL, *argv], capsys)
    assert_one_line_error(code, err, "evaluate.py: error", *expected)


@pytest.mark.rl
def test_evaluate_cli_corrupt_policy(tmp_path):
    argv, expected = _bad_evaluate_case("corrupt policy", tmp_path)
    result = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), *QUICK_EVAL, *argv],
                            capture_output=True, text=True, cwd=ROOT, timeout=300)  # fmt: skip
    assert_one_line_error(result.returncode, result.stderr, *expected)


# ------------------------------------------------------------------------ train.py (11-14)
FAST = ["--num-envs", "4", "--eval-episodes", "2", "--eval-episode-length", "1", "--no-progress"]


def edited_yml(algo: str, folder: Path, **changes: Any) -> Path:
    """A copy of hyperparams/<algo>.yml with some top-level entries replaced."""
    lines = (ROOT / "hyperparams" / f"{algo}.yml").read_text().splitlines()
    for key, value in changes.items():
        hits = [k for k, line in enumerate(lines) if line.startswith(f"  {key}:")]
        assert len(hits) == 1, key
        lines[hits[0]] = f"  {key}: {value}"
    path = folder / f"{algo}.yml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def ppo_yml(tmp_path_factory) -> Path:
    """PPO with 256-step rollouts: 4 vehicles x 256 = 1024 steps per rollout."""
    return edited_yml("ppo", tmp_path_factory.mktemp("hp"), n_steps=256, batch_size=256,
                      n_epochs=1)  # fmt: skip


def ppo_argv(yml: Path, out: Path, *extra: str) -> list[str]:
    return [*FAST, "--hyperparams", str(yml), "--output-dir", str(out), *extra]


def _raise_at(steps: int, exc: BaseException):
    from stable_baselines3.common.callbacks import BaseCallback

    class RaiseAt(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= steps:
                raise exc
            return True

    return RaiseAt()


class Killed(Exception):
    """Stands for SIGKILL / a power cut: no handler in train.py runs."""


@pytest.mark.rl
def test_wall_time_checkpoints_survive_a_hard_kill(train, ppo_yml, tmp_path):
    # checkpoint_freq keeps its default (500k steps: never in this run); checkpoints by wall
    # time at every rollout boundary (1024, 2048), then a kill in the third rollout
    argv = ppo_argv(ppo_yml, tmp_path, "--total-timesteps", "4096", "--eval-freq", "0",
                    "--checkpoint-minutes", "1e-6")  # fmt: skip
    with pytest.raises(Killed):
        train.train(train.parse_args(argv), extra_callbacks=[_raise_at(2600, Killed())])
    ckpts = sorted(p.name for p in (tmp_path / "checkpoints").glob("ckpt_*.zip"))
    assert ckpts == ["ckpt_000000001024.zip", "ckpt_000000002048.zip"]
    for name in ckpts:
        assert checkpoint_problem(tmp_path / "checkpoints" / name) is None
    resumed = train.train(train.parse_args([*argv, "--resume", "auto"]))
    assert resumed["num_timesteps"] == 4096 and resumed["model"].num_timesteps == 4096


@pytest.mark.rl
def test_the_end_of_training_is_always_checkpointed(train, ppo_yml, tmp_path):
    argv = ppo_argv(ppo_yml, tmp_path, "--total-timesteps", "1024", "--eval-freq", "0",
                    "--checkpoint-freq", "0")  # fmt: skip
    train.train(train.parse_args(argv))
    stem = tmp_path / "checkpoints" / "ckpt_000000001024"
    for suffix in (".zip", ".vecnormalize.pkl", ".json"):
        assert Path(str(stem) + suffix).is_file(), suffix
    assert checkpoint_problem(Path(str(stem) + ".zip")) is None
    meta = json.loads(Path(str(stem) + ".json").read_text())
    assert meta["num_timesteps"] == 1024
    assert set(meta["digests"]) == {"model", "normaliser"}  # by role, not by file name


@pytest.fixture(scope="module")
def two_checkpoints(train, ppo_yml, tmp_path_factory) -> Path:
    """A finished 2048-step PPO run with checkpoints at 1024 and 2048 steps."""
    out = tmp_path_factory.mktemp("two-ckpts")
    train.train(train.parse_args(ppo_argv(ppo_yml, out, "--total-timesteps", "2048",
                                          "--eval-freq", "0", "--checkpoint-freq", "1024")))  # fmt: skip
    assert len(list((out / "checkpoints").glob("ckpt_*.json"))) == 2
    return out


def _corrupt(ckpt_dir: Path, how: str) -> None:
    stem = ckpt_dir / "ckpt_000000002048"
    rng = np.random.default_rng(1)
    if how == "random bytes in the zip":
        Path(str(stem) + ".zip").write_bytes(rng.bytes(5000))
    elif how == "truncated statistics":
        pkl = Path(str(stem) + ".vecnormalize.pkl")
        pkl.write_bytes(pkl.read_bytes()[:100])
    elif how == "no json":
        Path(str(stem) + ".json").unlink()
    elif how == "garbage json":
        Path(str(stem) + ".json").write_bytes(rng.bytes(300))
    else:
        raise KeyError(how)


@pytest.mark.rl
@pytest.mark.parametrize(
    "how", ["random bytes in the zip", "truncated statistics", "no json", "garbage json"]
)
def test_latest_checkpoint_skips_damaged_ones(two_checkpoints, tmp_path, capsys, how):
    out = tmp_path / "run"
    shutil.copytree(two_checkpoints, out)
    _corrupt(out / "checkpoints", how)
    assert latest_checkpoint(out).name == "ckpt_000000001024.zip"
    err = capsys.readouterr().err
    assert "skipping" in err and "ckpt_000000002048" in err


@pytest.mark.rl
def test_resume_auto_falls_back_past_a_corrupt_newest_checkpoint(
    train, two_checkpoints, ppo_yml, tmp_path, capsys
):
    out = tmp_path / "run"
    shutil.copytree(two_checkpoints, out)
    _corrupt(out / "checkpoints", "random bytes in the zip")
    argv = ppo_argv(ppo_yml, out, "--total-timesteps", "3072", "--eval-freq", "0",
                    "--resume", "auto")  # fmt: skip
    summary = train.train(train.parse_args(argv))
    captured = capsys.readouterr()
    assert "skipping" in captured.err and "ckpt_000000002048.zip" in captured.err
    assert "resumed" in captured.out and "at 1024 timesteps" in captured.out
    assert summary["num_timesteps"] == 3072


@pytest.mark.rl
def test_resume_explicit_corrupt_checkpoint_is_one_line(train, two_checkpoints, ppo_yml, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(two_checkpoints, out)
    _corrupt(out / "checkpoints", "truncated statistics")
    ckpt = out / "checkpoints" / "ckpt_000000002048.zip"
    argv = ppo_argv(ppo_yml, out, "--total-timesteps", "3072", "--resume", str(ckpt))
    with pytest.raises(SystemExit) as info:
        train.train(train.parse_args(argv))
    assert_one_line_error(1, str(info.value.code), "ckpt_000000002048", "vecnormalize.pkl")


@pytest.fixture
def no_training(train, monkeypatch):
    """Fail the test if train.py builds its environment (i.e. starts)."""

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("training started before the output folders were checked")

    monkeypatch.setattr(train, "make_env", refuse)


@pytest.mark.rl
@pytest.mark.parametrize("flag", ["--output-dir", "--tensorboard"])
def test_unwritable_output_folders_stop_before_training(
    train, flag, ppo_yml, tmp_path, no_training
):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    argv = ppo_argv(ppo_yml, tmp_path / "out", "--total-timesteps", "1024")
    argv += [flag, str(blocker / "sub")]
    with pytest.raises(SystemExit) as info:
        train.train(train.parse_args(argv))
    assert_one_line_error(1, str(info.value.code), "train.py: error", flag, "a-file")


@pytest.mark.rl
@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--checkpoint-minutes", "-1"], "--checkpoint-minutes"),
        (["--keep-replay-buffers", "-1"], "--keep-replay-buffers"),
        (["--eval-episodes", "0"], "--eval-episodes"),
        (["--env-threads", "0"], "--env-threads"),
    ],
)
def test_train_bad_arguments_are_one_line(train, extra, expected, capsys):
    code, err = exit_of(train.parse_args, extra, capsys)
    assert_one_line_error(code, err, "train.py: error", expected)


@pytest.mark.rl
def test_train_too_short_evaluation_episode_is_one_line(train, ppo_yml, tmp_path, no_training):
    argv = ppo_argv(ppo_yml, tmp_path, "--eval-episode-length", "0.1")
    with pytest.raises(SystemExit) as info:
        train.train(train.parse_args(argv))
    assert_one_line_error(1, str(info.value.code), "--eval-episode-length", "0.335 s")


@pytest.mark.rl
def test_train_cli_unwritable_output_is_one_line(train, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    result = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), "--output-dir", str(blocker / "out"),
         "--no-progress"],
        capture_output=True, text=True, cwd=ROOT, timeout=300,
    )  # fmt: skip
    assert_one_line_error(result.returncode, result.stderr, "--output-dir", "a-file")


@pytest.mark.rl
def test_off_policy_checkpoints_keep_only_the_newest_replay_buffers(train, tmp_path, capsys):
    yml = edited_yml("sac", tmp_path, learning_starts=100, batch_size=32)
    out = tmp_path / "out"
    argv = [*FAST, "--hyperparams", str(yml), "--output-dir", str(out), "--algo", "sac",
            "--num-envs", "2", "--total-timesteps", "300", "--eval-freq", "0",
            "--checkpoint-freq", "50"]  # fmt: skip
    train.train(train.parse_args(argv))  # default --keep-replay-buffers 2
    ckpt_dir = out / "checkpoints"
    steps = [50, 100, 150, 200, 250, 300]
    assert sorted(p.name for p in ckpt_dir.glob("ckpt_*.zip")) == [
        f"ckpt_{s:012d}.zip" for s in steps
    ]
    assert sorted(p.name for p in ckpt_dir.glob("*.replay_buffer.pkl")) == [
        "ckpt_000000000250.replay_buffer.pkl", "ckpt_000000000300.replay_buffer.pkl"
    ]  # fmt: skip
    for s in steps:  # the pruned checkpoints stay intact
        assert checkpoint_problem(ckpt_dir / f"ckpt_{s:012d}.zip") is None
    # resuming from one whose buffer was pruned works, with an empty buffer, and says so
    capsys.readouterr()
    resumed = train.train(train.parse_args([*argv[:-2], "--checkpoint-freq", "0",
                                            "--total-timesteps", "400", "--resume",
                                            str(ckpt_dir / "ckpt_000000000100.zip")]))  # fmt: skip
    assert resumed["num_timesteps"] == 400
    assert "no replay buffer" in capsys.readouterr().err


# A full disk in a train.py process: PPO.save (case "save": from its third call, after the
# best model and the checkpoint at 1024 steps) or the evaluations.jsonl append (case "log":
# from its second line) stores half its data, then raises ENOSPC.
FULL_DISK_DRIVER = r"""
import builtins, errno, sys
from pathlib import Path
case, argv = sys.argv[1], sys.argv[2:]

def enospc():
    raise OSError(errno.ENOSPC, "No space left on device")

if case in ("save", "first"):  # "first": the disk is full from the first save on
    import stable_baselines3 as sb3
    real_save, calls = sb3.PPO.save, []
    def save(self, path, *args, **kwargs):
        calls.append(path)
        if len(calls) > (2 if case == "save" else 0):
            Path(path).write_bytes(b"PK\x03\x04 half a file")
            enospc()
        return real_save(self, path, *args, **kwargs)
    sb3.PPO.save = save
else:
    real_open, opened = builtins.open, []
    class Half:
        def __init__(self, fh): self.fh = fh
        def write(self, data):
            self.fh.write(data[: len(data) // 2]); self.fh.flush(); enospc()
        def __getattr__(self, name): return getattr(self.fh, name)
        def __enter__(self): return self
        def __exit__(self, *exc): self.fh.close()
    def fake_open(file, mode="r", *args, **kwargs):
        fh = real_open(file, mode, *args, **kwargs)
        if str(file).endswith("evaluations.jsonl") and "a" in mode:
            opened.append(file)
            if len(opened) > 1:
                return Half(fh)
        return fh
    builtins.open = fake_open
from capsule_env.agents.learning.train import main
sys.exit(main(argv))
"""


@pytest.mark.rl
@pytest.mark.parametrize("case", ["save", "log"])
def test_train_on_a_full_disk_is_one_line_and_the_files_stay_intact(train, ppo_yml, tmp_path, case):
    out = tmp_path / "run"
    argv = ppo_argv(ppo_yml, out, "--total-timesteps", "2048", "--eval-freq", "1024",
                    "--checkpoint-freq", "1024")  # fmt: skip
    result = subprocess.run([sys.executable, "-c", FULL_DISK_DRIVER, case, *argv],
                            capture_output=True, text=True, cwd=ROOT, timeout=300)  # fmt: skip
    assert_one_line_error(result.returncode, result.stderr, "train.py: error",
                          "No space left on device", "--resume auto")  # fmt: skip
    # what was saved before the disk filled is complete and loads; nothing half-written stays
    assert SB3Policy.load(out / "best_model.zip").meta["num_timesteps"] >= 1024
    assert checkpoint_problem(out / "checkpoints" / "ckpt_000000001024.zip") is None
    for folder in (out, out / "checkpoints"):
        assert [p.name for p in folder.iterdir() if p.name.startswith(".")] == []
    logged = [json.loads(x)["num_timesteps"] for x in (out / "evaluations.jsonl").open()]
    # whole lines only: the one cut by the full disk is gone (case "save": the 2048-step line
    # is there when that evaluation was not a new best, whose save would have failed first)
    assert logged == [1024] if case == "log" else logged in ([1024], [1024, 2048])
    # once space is freed, the printed command continues the run
    command = result.stderr.split("continue with: ")[1].split()
    assert command[3:] == ["--output-dir", str(out), "--resume", "auto", "--no-progress"]
    resumed = train.train(train.parse_args(command[3:]))
    assert resumed["num_timesteps"] == 2048
    logged = [json.loads(x)["num_timesteps"] for x in (out / "evaluations.jsonl").open()]
    assert logged[-1] == 2048 and saved_at(out / "final_model", 2048)


@pytest.mark.rl
def test_a_full_disk_before_any_checkpoint_offers_no_resume(train, ppo_yml, tmp_path):
    # issue 40: the message offered a --resume auto that cannot work when nothing was saved
    out = tmp_path / "run"
    argv = ppo_argv(ppo_yml, out, "--total-timesteps", "2048", "--eval-freq", "1024",
                    "--checkpoint-freq", "1024")  # fmt: skip
    result = subprocess.run([sys.executable, "-c", FULL_DISK_DRIVER, "first", *argv],
                            capture_output=True, text=True, cwd=ROOT, timeout=300)  # fmt: skip
    assert_one_line_error(result.returncode, result.stderr, "train.py: error",
                          "No space left on device", "no checkpoint was saved")  # fmt: skip
    assert "--resume" not in result.stderr and f"remove {out}" in result.stderr
    assert not any((out / "checkpoints").glob("ckpt_*.zip"))


# ---------------------------------------------------------------- python -m identify (16)
def _write_mat(path: Path, n: int = 400, **override: Any) -> Path:
    """A small file shaped like the Labcontrol ones (``Tout`` (n, 1), ``x_F`` (n, 3): mm,
    mm/s, N, ``dist``/``forc`` copies, scalar ``Ts``): a 1 Hz, 0..25 mm stroke and a
    hysteretic viscous-plus-friction force with a preload and 3 N of measurement noise (a
    noise-free force fits too well for a measurement: the identification would warn)."""
    ts = 0.01
    t = np.arange(n) * ts
    x = 12.5 + 12.5 * np.sin(2 * np.pi * t)
    v = 12.5 * 2 * np.pi * np.cos(2 * np.pi * t)
    noise = np.random.default_rng(0).normal(0.0, 3.0, n)
    f = 300 * np.tanh((v + 0.5 * (x - 12.5)) / 20) + 2.0 * v + 50 + noise
    x_f = np.column_stack([x, v, f])
    data = {"Tout": t[:, None], "x_F": x_f, "dist": x_f[:, :1], "forc": x_f[:, 2:], "Ts": ts}
    data.update(override)
    sio.savemat(str(path), data)
    return path


def _identify_case(case: str, tmp: Path) -> Path:
    good = _write_mat(tmp / "good.mat")
    x_f = sio.loadmat(str(good))["x_F"]
    if case == "constant force":
        x_f[:, 2] = 7.0
        return _write_mat(tmp / "constant.mat", x_F=x_f)
    if case == "empty Ts":
        return _write_mat(tmp / "empty_ts.mat", Tout=np.zeros((0, 0)), Ts=np.zeros((0, 0)))
    if case == "complex data":
        return _write_mat(tmp / "complex.mat", x_F=x_f * (1 + 0.5j))
    if case == "overflowing values":
        return _write_mat(tmp / "huge.mat", x_F=x_f * 1e300)
    if case == "infinite values":
        x_f[5, 1] = np.inf
        return _write_mat(tmp / "inf.mat", x_F=x_f)
    raise KeyError(case)


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("constant force", "constant"),
        ("empty Ts", "'Ts'"),
        ("complex data", "complex"),
        ("overflowing values", "1e+09"),
        ("infinite values", "infinite"),
    ],
)
def test_identify_bad_data_is_one_line_naming_the_file(case, expected, tmp_path, capsys):
    path = _identify_case(case, tmp_path)
    code, err = exit_of(identify.main, ["--data", str(path)], capsys)
    assert_one_line_error(code, err, str(path), expected)
    assert code == 2


def test_identify_a_good_synthetic_file_still_fits(tmp_path, capsys):
    out = tmp_path / "fit.json"
    path = _write_mat(tmp_path / "good.mat")
    assert identify.main(["--data", str(path), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    peak = data["peak_force_n"]
    assert peak > 0 and data["models"]["tanh"]["rmse_n"] < 0.2 * peak


@pytest.mark.parametrize("case", ["json is a folder", "json in a non-folder", "plots is a file"])
def test_identify_unwritable_outputs_stop_before_fitting(case, tmp_path, capsys, monkeypatch):
    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("the fit ran before the output paths were checked")

    monkeypatch.setattr(identify, "identify_measured", refuse)
    path = _write_mat(tmp_path / "good.mat")
    (tmp_path / "file").write_text("x")
    option, target, expected = {
        "json is a folder": ("--json", tmp_path, "is a folder"),
        "json in a non-folder": ("--json", tmp_path / "file" / "fit.json", "not a folder"),
        "plots is a file": ("--plots", tmp_path / "file", "is a file"),
    }[case]
    code, err = exit_of(identify.main, ["--data", str(path), option, str(target)], capsys)
    assert_one_line_error(code, err, option, str(target), expected)


def test_identify_json_on_a_full_disk_keeps_the_previous_file(tmp_path, full_disk, capsys):
    path = _write_mat(tmp_path / "good.mat")
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    out = out_dir / "fit.json"
    out.write_text('{"previous": true}')
    full_disk(out_dir)
    code, err = exit_of(identify.main, ["--data", str(path), "--json", str(out)], capsys)
    assert_one_line_error(code, err, "No space")
    assert files_of(out_dir) == {"fit.json": b'{"previous": true}'}
