"""train.py refuses before it makes anything on disk (issue 40): bad arguments, files and
hyperparameters stop it in one line with no folder left behind, and a run killed before its
first checkpoint leaves a folder no new run is started in."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import NO_SB3, NO_YAML

pytest.importorskip("stable_baselines3", reason=NO_SB3)
pytest.importorskip("yaml", reason=NO_YAML)  # the hyperparameter files

from capsule_env.agents.learning import train  # noqa: E402
from test_train import ROOT, edited_yml, fast_args  # noqa: E402

pytestmark = pytest.mark.rl


@pytest.fixture(scope="module")
def tiny_yml(tmp_path_factory) -> Path:
    return edited_yml("ppo", tmp_path_factory.mktemp("hp"), n_steps=256, batch_size=256,
                      n_epochs=2)  # fmt: skip


def _everything(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _bad_files(folder: Path) -> dict[str, str]:
    """What the placeholders of REFUSED stand for: files in ``folder``."""
    (folder / "key").mkdir()
    (folder / "batch").mkdir()
    (folder / "a-file").write_text("not a folder")
    return {
        "MISSING": str(folder / "missing.yml"),
        "BLOCKER": str(folder / "a-file"),
        "TB": str(folder / "tb"),
        "BAD_KEY": str(
            edited_yml("ppo", folder / "key", n_steps=256, clip_range="0.2\n  bogus_key: 3")
        ),  # fmt: skip
        "BAD_BATCH": str(edited_yml("ppo", folder / "batch", n_steps=256, batch_size=1)),
    }


REFUSED = [
    (["--resume", "auto"], "--resume auto: no checkpoint in"),
    (["--hyperparams", "MISSING"], "hyperparameter file not found"),
    (["--task", "Bogus-v0"], "--task must be one of"),
    (["--eval-episode-length", "0.001"], "--eval-episode-length 0.001 s is shorter"),
    (["--env", "speed_kmh=-5", "--tensorboard", "TB"], "speed_kmh must be in"),
    (["--tensorboard", "BLOCKER/tb"], "is not a writable folder (BLOCKER is a file)"),
    (["--hyperparams", "BAD_KEY"], "do not make a PPO: PPO.__init__() got an unexpected "
     "keyword argument 'bogus_key'"),
    (["--hyperparams", "BAD_BATCH"], "do not make a PPO: `batch_size` must be greater than 1"),
]  # fmt: skip


@pytest.mark.parametrize(("given", "expected"), REFUSED)
def test_a_refused_run_makes_nothing_on_disk(tiny_yml, tmp_path, given, expected):
    # issue 40: --seed out of range left an empty run folder, and so did every refusal made
    # after the folders were made (a --resume auto of a mistyped folder, a missing file, a bad
    # task or env argument; --tensorboard's folder too); bad hyperparameters were a traceback
    files = _bad_files(tmp_path)
    before = _everything(tmp_path)

    def swap(word: str) -> str:
        for placeholder, path in files.items():
            word = word.replace(placeholder, path)
        return word

    argv = fast_args(tiny_yml, tmp_path / "run", "--total-timesteps", "256",
                     *(swap(word) for word in given))  # fmt: skip
    with pytest.raises(SystemExit) as stop:
        train.train(train.parse_args(argv))
    message = str(stop.value.code)
    assert message.startswith("train.py: error: ") and "\n" not in message
    assert swap(expected) in message, message
    assert _everything(tmp_path) == before  # no run folder, no TensorBoard folder


def test_bad_hyperparameters_are_one_line_on_the_command_line(tmp_path):
    yml = edited_yml("ppo", tmp_path, n_steps=256, clip_range="0.2\n  bogus_key: 3")
    out = tmp_path / "run"
    result = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *fast_args(yml, out, "--total-timesteps", "256")],
        capture_output=True, text=True, cwd=ROOT, timeout=300,
    )  # fmt: skip
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.returncode == 1 and len(lines) == 1 and "Traceback" not in result.stderr
    assert lines[0].startswith(f"train.py: error: the hyperparameters ({yml}) do not make a PPO")
    assert not out.exists()


@pytest.mark.parametrize(("seed", "episodes"), [("-1", "10"), (str(2**63 - 1), "2")])
def test_an_evaluation_seed_out_of_range_is_one_line(seed, episodes, capsys):
    # it trained to the first evaluation and then stopped with numpy's traceback
    with pytest.raises(SystemExit) as stop:
        train.parse_args(["--eval-seed", seed, "--eval-episodes", episodes])
    err = capsys.readouterr().err.strip()
    assert stop.value.code == 2 and "\n" not in err
    last = 2**63 - int(episodes)
    assert f"--eval-seed must be in 0..{last} (--eval-episodes {episodes} seeds" in err
    assert train.parse_args(["--eval-seed", str(last), "--eval-episodes", episodes])


KILL_AFTER_FIRST_EVALUATION = """
import os, signal, sys
from stable_baselines3.common.callbacks import BaseCallback
from capsule_env.agents.learning import train

class Kill(BaseCallback):  # SIGKILL: no Ctrl-C checkpoint, no final save
    def _on_step(self):
        if self.num_timesteps > 1024:
            os.kill(os.getpid(), signal.SIGKILL)
        return True

train.train(train.parse_args(sys.argv[1:]), extra_callbacks=[Kill()])
"""


def test_a_run_killed_before_its_first_checkpoint_is_not_mixed_with_a_new_one(tiny_yml, tmp_path):
    out = tmp_path / "run"
    argv = fast_args(tiny_yml, out, "--total-timesteps", "2048", "--eval-freq", "1024",
                     "--checkpoint-freq", "0", "--checkpoint-minutes", "0")  # fmt: skip
    killed = subprocess.run([sys.executable, "-c", KILL_AFTER_FIRST_EVALUATION, *argv],
                            capture_output=True, text=True, cwd=ROOT, timeout=300)  # fmt: skip
    assert killed.returncode == -9, killed.stderr[-2000:]
    left = {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert {"best_model.zip", "evaluations.jsonl"} <= set(left)  # its first evaluation
    assert not any((out / "checkpoints").glob("ckpt_*"))
    expected = {  # a new run into it; continuing it
        "fresh": "holds another run's files (best_model.json, best_model.vecnormalize.pkl, "
        "best_model.zip and 1 more): it has no checkpoint to continue from",
        "--resume": "--resume auto: no checkpoint in",
    }
    for case, again in (("fresh", argv), ("--resume", [*argv, "--resume", "auto"])):
        with pytest.raises(SystemExit) as stop:
            train.train(train.parse_args(again))
        message = str(stop.value.code)
        assert "\n" not in message and expected[case] in message, message
        assert {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()} == left


# ------------------------------------------------------------- one process per run folder
def _hold_lock(folder: Path) -> int:
    """Lock ``folder`` as another train.py working in it does; returns the descriptor."""
    import os

    fcntl = pytest.importorskip("fcntl")  # flock (where there is none, train.py takes none)
    fd = os.open(folder, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    return fd


def test_a_folder_another_run_works_in_is_left_alone(tiny_yml, tmp_path):
    # issue 40: a second train.py in a folder wrote over the first's files (two started at
    # once) or removed its save in progress (a --resume auto while it ran: prepare's cleanup)
    import os

    out = tmp_path / "run"
    (out / "checkpoints").mkdir(parents=True)
    in_progress = out / ".best_model.zip.0123abcd.tmp"  # a save being written
    in_progress.write_bytes(b"PK half a model")
    fd = _hold_lock(out)
    try:
        for extra in ([], ["--resume", "auto"]):
            with pytest.raises(SystemExit) as stop:
                train.train(train.parse_args(fast_args(tiny_yml, out, *extra)))
            message = str(stop.value.code)
            assert "\n" not in message
            assert f"--output-dir {out} is in use by another train.py" in message
            assert in_progress.read_bytes() == b"PK half a model"
    finally:
        os.close(fd)


@pytest.mark.parametrize("other", ["running", "finished"])
def test_two_new_runs_started_at_once_into_one_folder(tiny_yml, tmp_path, monkeypatch, other):
    # both look at the folder before either makes it: the second to make it is refused
    import os

    from capsule_env.agents.learning import training

    out = tmp_path / "run"
    real = training.make_run_folders
    held: list[int] = []

    def the_other_run_first(plan):  # it made the folder since this run looked
        (out / "checkpoints").mkdir(parents=True)
        if other == "running":
            held.append(_hold_lock(out))
        else:
            (out / "evaluations.jsonl").write_text('{"num_timesteps": 1024}\n')
        real(plan)

    monkeypatch.setattr(train, "make_run_folders", the_other_run_first)
    try:
        with pytest.raises(SystemExit) as stop:
            train.train(train.parse_args(fast_args(tiny_yml, out, "--total-timesteps", "256")))
    finally:
        for fd in held:
            os.close(fd)
    expected = "is in use by another train.py" if other == "running" else "holds another run's"
    assert expected in str(stop.value.code)
    assert {p.name for p in out.rglob("*")} <= {"checkpoints", "evaluations.jsonl"}
