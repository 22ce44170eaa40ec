"""train.py: a short run end to end, the saved files load for evaluation, resume, SAC/TD3, CLI."""

from __future__ import annotations

import copy
import json
import pickle
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import NO_SB3, NO_YAML

pytest.importorskip("stable_baselines3", reason=NO_SB3)
pytest.importorskip("yaml", reason=NO_YAML)  # the hyperparameter files

from capsule_env.agents.learning import (
    hyperparams,  # noqa: E402
    train,  # noqa: E402
    training,
)
from capsule_env.agents.learning.sb3_policy import ALGORITHMS, SB3Policy  # noqa: E402

from capsule_env.evaluation import evaluate  # noqa: E402

pytestmark = pytest.mark.rl

ROOT = Path(__file__).resolve().parent.parent
# Small and fast: 4 vehicles, 256-step PPO rollouts (1024 samples per update), a 2-episode,
# 1-second evaluation.
FAST = [
    "--num-envs", "4", "--eval-episodes", "2", "--eval-episode-length", "1",
    "--no-progress", "--hyperparams", "",
]  # fmt: skip


def edited_yml(algo: str, folder: Path, **changes: Any) -> Path:
    """A copy of hyperparams/<algo>.yml with some top-level entries replaced (no PyYAML)."""
    lines = (ROOT / "hyperparams" / f"{algo}.yml").read_text().splitlines()
    for key, value in changes.items():
        hits = [k for k, line in enumerate(lines) if re.match(rf"^  {key}:", line)]
        assert len(hits) == 1, key
        lines[hits[0]] = f"  {key}: {value}"
    path = folder / f"{algo}.yml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def tiny_ppo_yml(tmp_path_factory) -> Path:
    """hyperparams/ppo.yml with a short rollout and small batches (same format and keys)."""
    return edited_yml("ppo", tmp_path_factory.mktemp("hp"), n_steps=256, batch_size=256,
                      n_epochs=2)  # fmt: skip


def fast_args(yml: Path, out: Path, *extra: str) -> list[str]:
    args = list(FAST)
    args[args.index("--hyperparams") + 1] = str(yml)
    return [*args, "--output-dir", str(out), *extra]


@pytest.fixture(scope="module")
def ppo_run(tiny_ppo_yml, tmp_path_factory):
    out = tmp_path_factory.mktemp("ppo")
    argv = fast_args(tiny_ppo_yml, out, "--total-timesteps", "2048", "--eval-freq", "1024",
                     "--name", "tiny-ppo")  # fmt: skip
    summary = train.train(train.parse_args(argv))
    return out, summary


def test_short_ppo_run_writes_models_and_evaluates(ppo_run, tmp_path):
    out, summary = ppo_run
    assert summary["num_timesteps"] == 2048 and not summary["interrupted"]
    for stem in ("best_model", "final_model"):
        for suffix in (".zip", ".vecnormalize.pkl", ".json"):
            assert (out / f"{stem}{suffix}").is_file(), f"{stem}{suffix} missing"
    meta = json.loads((out / "best_model.json").read_text())
    assert meta["name"] == "tiny-ppo" and meta["algo"] == "ppo"
    assert meta["env_kwargs"]["setting"] == "hils"
    assert meta["env_kwargs"]["action_mode"] == "force"
    assert "guideway_seed" not in meta["env_kwargs"]  # chosen by the evaluation
    assert meta["eval"]["guideway_seed"] == 7  # the validation bank: never the evaluation one
    assert np.isfinite(meta["eval"]["metrics"]["wk_rms_body_acc_m_s2"])
    assert "vre_pct" in meta["eval"]["metrics"]
    assert meta["num_timesteps"] > 0 and meta["wall_time_s"] > 0
    final = json.loads((out / "final_model.json").read_text())
    assert final["num_timesteps"] == 2048
    lines = (out / "evaluations.jsonl").read_text().splitlines()
    assert len(lines) == 2  # at 1024 and at 2048 (the end)

    report = tmp_path / "eval.json"
    rc = evaluate.main([
        "--policy", str(out / "best_model.zip"), "--episodes", "2", "--episode-length", "1",
        "--setting", "hils", "--controllers", "passive", "--no-shipped-policy",
        "--json", str(report),
    ])  # fmt: skip
    assert rc == 0
    controllers = json.loads(report.read_text())["settings"]["hils"]["controllers"]
    assert "tiny-ppo" in controllers and "passive" in controllers
    assert np.isfinite(controllers["tiny-ppo"]["wk_rms_body_acc_m_s2"])


def test_saved_policy_matches_trained_model(ppo_run):
    out, summary = ppo_run
    model = summary["model"]  # the model at the end of training = final_model.*
    with (out / "final_model.vecnormalize.pkl").open("rb") as fh:
        vec_normalize = pickle.load(fh)
    policy = SB3Policy.load(out / "final_model.zip")
    assert policy.meta["algo"] == "ppo"
    rng = np.random.default_rng(0)
    dim = vec_normalize.obs_rms.mean.shape[0]
    obs = (rng.normal(size=(16, dim)) * np.sqrt(vec_normalize.obs_rms.var)
           + vec_normalize.obs_rms.mean).astype(np.float32)  # fmt: skip
    expected, _ = model.predict(vec_normalize.normalize_obs(obs), deterministic=True)
    got, _ = policy.predict(obs)
    np.testing.assert_allclose(got, np.clip(expected, -1, 1), rtol=1e-6, atol=1e-6)
    # and the live training statistics are the saved ones
    live_env = model.get_vec_normalize_env()
    np.testing.assert_array_equal(live_env.obs_rms.mean, vec_normalize.obs_rms.mean)
    # the in-memory policy train.py evaluates is the one evaluate.py loads, with a snapshot of
    # the statistics (not the live object that training goes on updating)
    live = SB3Policy.from_model(model, live_env, {"name": "live"})
    assert live.obs_rms is not live_env.obs_rms and live.name == "live"
    np.testing.assert_array_equal(live.predict(obs)[0], got)


class _StopAt:
    """A callback that presses Ctrl-C once ``num_timesteps`` reaches ``steps``."""

    def __new__(cls, steps: int):
        from stable_baselines3.common.callbacks import BaseCallback

        class StopAt(BaseCallback):
            def _on_step(self) -> bool:
                if self.num_timesteps >= steps:
                    raise KeyboardInterrupt
                return True

        return StopAt()


def _statistics_at_start():
    from stable_baselines3.common.callbacks import BaseCallback

    class Capture(BaseCallback):
        seen: dict = {}

        def _on_training_start(self) -> None:
            env = self.model.get_vec_normalize_env()
            Capture.seen = {
                "mean": env.obs_rms.mean.copy(),
                "var": env.obs_rms.var.copy(),
                "count": env.obs_rms.count,
                "ret_var": env.ret_rms.var.copy(),
                "first_obs": env.get_original_obs().copy(),
                "num_timesteps": self.model.num_timesteps,
            }

        def _on_step(self) -> bool:
            return True

    return Capture


def test_interrupt_then_resume_auto(tiny_ppo_yml, tmp_path):
    argv = fast_args(tiny_ppo_yml, tmp_path, "--total-timesteps", "3072", "--eval-freq", "0",
                     "--checkpoint-freq", "0")  # fmt: skip
    # Ctrl-C half-way through the second rollout (4 x 256 = 1024 steps each): a checkpoint is
    # saved, counting only the steps learned from (the first rollout).
    first = train.train(train.parse_args(argv), extra_callbacks=[_StopAt(1536)])
    assert first["interrupted"] and first["num_timesteps"] == 1024
    ckpt = tmp_path / "checkpoints" / "ckpt_000000001024"
    for suffix in (".zip", ".vecnormalize.pkl", ".json"):
        assert Path(str(ckpt) + suffix).is_file()
    assert json.loads(Path(str(ckpt) + ".json").read_text())["num_timesteps"] == 1024
    assert not (tmp_path / "final_model.zip").exists()
    with open(str(ckpt) + ".vecnormalize.pkl", "rb") as fh:
        saved = pickle.load(fh)

    capture = _statistics_at_start()
    second = train.train(train.parse_args([*argv, "--resume", "auto"]), extra_callbacks=[capture()])
    seen = capture.seen
    assert seen["num_timesteps"] == 1024  # not reset
    # Training goes on from the checkpoint's statistics plus the one batch of observations of
    # the env reset that starts learn() (SB3's public resume API: Algo.load + learn with
    # reset_num_timesteps=False), and nothing else.
    assert seen["first_obs"].shape == (4, saved.obs_rms.mean.shape[0])
    expected = copy.deepcopy(saved.obs_rms)
    expected.update(seen["first_obs"])
    assert seen["count"] == saved.obs_rms.count + 4 == expected.count
    np.testing.assert_allclose(seen["mean"], expected.mean, rtol=1e-12, atol=0)
    np.testing.assert_allclose(seen["var"], expected.var, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(seen["ret_var"], saved.ret_rms.var)
    assert second["num_timesteps"] == 3072 and not second["interrupted"]
    final = json.loads((tmp_path / "final_model.json").read_text())
    assert final["num_timesteps"] == 3072
    assert final["wall_time_s"] >= json.loads(Path(str(ckpt) + ".json").read_text())["wall_time_s"]


def test_resume_without_checkpoint_is_a_clear_error(tiny_ppo_yml, tmp_path):
    with pytest.raises(SystemExit, match="no checkpoint"):
        train.train(train.parse_args(fast_args(tiny_ppo_yml, tmp_path, "--resume", "auto")))


@pytest.mark.parametrize("bank", [2026, 7])
def test_training_on_a_held_out_bank_is_refused(tiny_ppo_yml, tmp_path, bank, capsys):
    # the evaluation bank (reported) and the validation bank (model selection) stay unseen
    argv = fast_args(tiny_ppo_yml, tmp_path, "--env", f"guideway_seed={bank}")
    with pytest.raises(SystemExit):
        train.train(train.parse_args(argv))
    assert f"guideway_seed={bank} is a held-out bank" in capsys.readouterr().err


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_off_policy_tiny_run_and_resume(algo, tmp_path):
    # learning_starts below the run length so that gradient steps happen
    small = edited_yml(algo, tmp_path, learning_starts=100, batch_size=32)
    argv = fast_args(small, tmp_path, "--algo", algo, "--num-envs", "2", "--total-timesteps",
                     "300", "--eval-freq", "0", "--checkpoint-freq", "200",
                     "--name", f"tiny-{algo}")  # fmt: skip
    summary = train.train(train.parse_args(argv))
    assert summary["num_timesteps"] == 300
    ckpt = tmp_path / "checkpoints" / "ckpt_000000000200"
    assert Path(str(ckpt) + ".replay_buffer.pkl").is_file()
    policy = SB3Policy.load(tmp_path / "best_model.zip")
    assert policy.meta["algo"] == algo
    dim = policy.obs_rms.mean.shape[0]
    action, _ = policy.predict(np.zeros((3, dim), dtype=np.float32))
    assert action.shape == (3, 1) and np.all(np.abs(action) <= 1)
    # resume from the 200-step checkpoint (replay buffer restored) up to 400 steps
    resumed = train.train(train.parse_args([
        *argv[: argv.index("--total-timesteps")], "--total-timesteps", "400",
        *argv[argv.index("--total-timesteps") + 2:], "--resume", str(ckpt) + ".zip",
    ]))  # fmt: skip
    assert resumed["num_timesteps"] == 400
    assert resumed["model"].replay_buffer.size() > 0


def test_hyperparameter_files_parse():
    for algo in ALGORITHMS:
        hp = hyperparams.load_hyperparams(ROOT / "hyperparams" / f"{algo}.yml")
        for key in ("n_envs", "n_timesteps", "policy", "gamma", "env_kwargs"):
            assert key in hp, f"{algo}.yml: {key}"
        kwargs = hyperparams.algo_kwargs_from(hp)
        assert isinstance(kwargs["policy_kwargs"], dict)
        assert hyperparams.normalize_kwargs_from(hp)["gamma"] == hp["gamma"]
        hyperparams.resolve_env_kwargs(hp["env_kwargs"], {})
    ppo = hyperparams.load_hyperparams(ROOT / "hyperparams" / "ppo.yml")
    assert ppo["n_timesteps"] == 4e6 and ppo["learning_rate"] == "lin_1e-3"
    schedule = hyperparams.algo_kwargs_from(ppo)["learning_rate"]
    assert schedule(1.0) == pytest.approx(1e-3) and schedule(0.5) == pytest.approx(5e-4)


def test_the_default_task_is_the_ride_task(tmp_path):
    """train.py with no env argument, and every shipped hyperparameter file, train on the
    registered ride task's options (hils plant, measured signals; force requests)."""
    import gymnasium as gym

    import capsule_env  # noqa: F401  (registers the tasks)

    ride = {"action_mode": "force", **gym.spec("CapsuleRide-v0").kwargs}
    assert ride == {"setting": "hils", "observation": "measured", "action_mode": "force"}
    assert hyperparams.resolve_env_kwargs({}, {}) == ride
    for algo in ALGORITHMS:
        hp = hyperparams.load_hyperparams(ROOT / "hyperparams" / f"{algo}.yml")
        assert hp["env_kwargs"] == ride, f"{algo}.yml"
    plan = training.prepare(train.parse_args(["--output-dir", str(tmp_path)]))
    assert plan.env_kwargs == ride and plan.args.algo == "ppo"


def test_policy_kwargs_are_read_without_eval():
    import torch.nn as nn

    read = hyperparams.algo_kwargs_from
    kwargs = read(
        {
            "policy_kwargs": "dict(net_arch=dict(pi=[64, 64], vf=[32]), "
            "activation_fn=nn.Tanh, log_std_init=-1.0, ortho_init=False)"
        }
    )
    assert kwargs["policy_kwargs"] == {"net_arch": {"pi": [64, 64], "vf": [32]},
                                       "activation_fn": nn.Tanh, "log_std_init": -1.0,
                                       "ortho_init": False}  # fmt: skip
    literal = read({"policy_kwargs": "{'net_arch': [8, (4, 2)], 'activation_fn': nn.GELU}"})
    assert literal["policy_kwargs"] == {"net_arch": [8, (4, 2)], "activation_fn": nn.GELU}
    assert hyperparams.normalize_kwargs_from({"normalize": "dict(norm_reward=False)"}) == {
        "norm_obs": True, "norm_reward": False, "clip_obs": 10.0, "gamma": 0.99
    }  # fmt: skip
    bad = {
        "__import__('os').system('echo no')": "policy_kwargs",
        "dict(activation_fn=nn.Module)": "policy_kwargs.activation_fn",
        "dict(net_arch=[64, len('ab')])": "policy_kwargs.net_arch",
        "dict(activation_fn=open)": "policy_kwargs.activation_fn",
        "dict(**{'a': 1})": "policy_kwargs",
        "dict(net_arch=[64, 64]": "policy_kwargs",
        "[64, 64]": "policy_kwargs",
        "{1: 2}": "policy_kwargs",
    }
    for text, key in bad.items():
        with pytest.raises(ValueError) as info:
            read({"policy_kwargs": text})
        message = str(info.value)
        assert message.startswith(f"{key}: ") and "\n" not in message, (text, message)
    with pytest.raises(ValueError, match="normalize"):
        hyperparams.normalize_kwargs_from({"normalize": "dict(norm_obs=exit())"})
    with pytest.raises(ValueError, match="learning_rate"):
        read({"learning_rate": "exp_1e-3"})


def test_env_arguments_merge_and_validate():
    args = train.parse_args(["--env-kwargs", '{"speed_kmh": 600}', "--env", "setting=sim",
                             "--env", "guideway_params={'peak_m': 0.01}"])  # fmt: skip
    assert args.env_kwargs == {"speed_kmh": 600, "setting": "sim",
                               "guideway_params": {"peak_m": 0.01}}  # fmt: skip
    assert train.parse_args(["--env-kwargs", "{'speed_kmh': 500.0}"]).env_kwargs == {
        "speed_kmh": 500.0
    }
    merged = hyperparams.resolve_env_kwargs({"observation": "full_state"}, {"setting": "sim"})
    assert merged["action_mode"] == "force" and merged["setting"] == "sim"
    assert merged["observation"] == "full_state"
    with pytest.raises(ValueError, match="setting"):
        hyperparams.resolve_env_kwargs({}, {"setting": "moon"})
    with pytest.raises(ValueError, match="speed_kmh"):
        hyperparams.resolve_env_kwargs({}, {"speed_kmh": -3})
    with pytest.raises(ValueError, match="speed_kmh"):
        hyperparams.resolve_env_kwargs({}, {"speed_kmh": "fast"})


def _run_cli(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *argv],
        capture_output=True, text=True, cwd=ROOT, timeout=120,
    )  # fmt: skip


def test_cli_help():
    result = _run_cli("--help")
    assert result.returncode == 0
    for flag in ("--algo", "--total-timesteps", "--env", "--resume", "--checkpoint-freq",
                 "--eval-freq", "--tensorboard", "--threads", "--hyperparams"):  # fmt: skip
        assert flag in result.stdout


def test_cli_bad_env_value_names_the_key(tmp_path):
    result = _run_cli("--env", "setting=moon", "--output-dir", str(tmp_path))
    assert result.returncode != 0
    assert "setting" in result.stderr and "moon" in result.stderr
    result = _run_cli("--env", "no_such_option=1", "--output-dir", str(tmp_path))
    assert result.returncode != 0 and "no_such_option" in result.stderr
    result = _run_cli("--env", "setting", "--output-dir", str(tmp_path))
    assert result.returncode != 0 and "KEY=VALUE" in result.stderr


# ------------------------------------------------------------- --resume restores the run
@pytest.fixture(scope="module")
def measured_run(tiny_ppo_yml, tmp_path_factory):
    """A 2048-step run with ``--env observation=measured`` (the file says full_state) and a
    2-episode evaluation every 1024 steps, Ctrl-C'd in its second rollout: a checkpoint at
    1024 steps. Returns the folder and what the Ctrl-C printed."""
    out = tmp_path_factory.mktemp("measured") / "run"
    argv = fast_args(tiny_ppo_yml, out, "--total-timesteps", "2048", "--eval-freq", "1024",
                     "--env", "observation=measured", "--seed", "3")  # fmt: skip
    import contextlib
    import io

    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        first = train.train(train.parse_args(argv), extra_callbacks=[_StopAt(1536)])
    assert first["interrupted"] and first["num_timesteps"] == 1024
    return out, printed.getvalue()


def _copy_run(run: Path, tmp_path: Path) -> Path:
    import shutil

    shutil.copytree(run, tmp_path / "run")
    return tmp_path / "run"


def test_bare_resume_auto_continues_the_run_with_its_own_arguments(measured_run, tmp_path):
    import shlex

    from capsule_env.engine.config import EnvConfig

    run, printed = measured_run
    out = _copy_run(run, tmp_path)
    # the printed command, as a user would paste it (in the folder it names)
    line = [x for x in printed.splitlines() if x.startswith("continue with: ")][0]
    words = shlex.split(line[len("continue with: ") :])
    assert words[:3] == ["python", "-m", "capsule_env.agents.learning.train"]
    assert words[3:] == ["--output-dir", str(run), "--resume", "auto", "--no-progress"]
    words[words.index(str(run))] = str(out)
    summary = train.train(train.parse_args(words[3:]))
    # its budget (2048, not the file's 4M), its observation (measured: 9 values, not the
    # file's full_state: 10), its vehicles (4, not the file's 32), its seed
    measured = len(EnvConfig.from_kwargs(setting="hils", observation="measured").observation_names)
    assert measured == 9
    assert summary["num_timesteps"] == 2048 and not summary["interrupted"]
    model = summary["model"]
    assert model.observation_space.shape == (measured,) and model.n_envs == 4
    final = json.loads((out / "final_model.json").read_text())
    assert final["env_kwargs"]["observation"] == "measured" and final["seed"] == 3
    assert final["hyperparams"]["n_steps"] == 256  # the run's file, not hyperparams/ppo.yml
    assert final["args"]["total_timesteps"] == 2048 and final["args"]["eval_episodes"] == 2
    lines = (out / "evaluations.jsonl").read_text().splitlines()
    assert [json.loads(x)["num_timesteps"] for x in lines] == [1024, 2048]


def test_resume_of_a_run_folder_restores_the_same_arguments(measured_run, tmp_path):
    from capsule_env.agents.learning.training import prepare

    out = _copy_run(measured_run[0], tmp_path)
    for argv in (["--resume", str(out)], ["--resume", str(out / "checkpoints" / "ckpt_000000001024.zip")]):  # fmt: skip
        plan = prepare(train.parse_args(argv))
        assert plan.output_dir == out and plan.env_kwargs["observation"] == "measured"
        assert plan.total == 2048 and plan.num_envs == 4 and plan.args.seed == 3
        assert plan.args.eval_episode_length == 1.0 and plan.hp["n_steps"] == 256
    # given again with the run's values (or an env default it already had): accepted
    same = ["--resume", "auto", "--output-dir", str(out), "--env", "observation=measured",
            "--seed", "3", "--env", "setting=hils", "--env", "reward_energy_weight=0.01"]  # fmt: skip
    assert prepare(train.parse_args(same)).env_kwargs["observation"] == "measured"
    # a longer budget is an explicit choice: it holds, and is said
    longer = prepare(train.parse_args(["--resume", str(out), "--total-timesteps", "3072"]))
    assert longer.total == 3072


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        (["--env", "observation=full_state"], ["--env observation='full_state'", "'measured'"]),
        (["--env", "speed_kmh=500"], ["--env speed_kmh=500", "not set: the env's default"]),
        (["--seed", "0"], ["--seed 0", "run's 3"]),
        (["--algo", "sac"], ["--algo 'sac'", "'ppo'"]),
        (["--num-envs", "8"], ["--num-envs 8", "run's 4"]),
        (["--eval-episodes", "5"], ["--eval-episodes 5", "run's 2"]),
        (["--hyperparams", "OTHER"], ["--hyperparams", "n_steps: 512 there, 256 in the run"]),
    ],
)
def test_resume_refuses_an_argument_that_differs_from_the_run(
    measured_run, tmp_path, monkeypatch, given, expected
):
    out = _copy_run(measured_run[0], tmp_path)
    if "OTHER" in given:
        given = ["--hyperparams", str(edited_yml("ppo", tmp_path, n_steps=512, batch_size=256,
                                                  n_epochs=2))]  # fmt: skip
    monkeypatch.setattr(train, "make_env", lambda *a, **k: pytest.fail("training started"))
    argv = ["--resume", "auto", "--output-dir", str(out), "--no-progress", *given]
    with pytest.raises(SystemExit) as info:
        train.train(train.parse_args(argv))
    message = str(info.value.code)
    assert "\n" not in message and message.startswith("train.py: error: --resume: ")
    for text in (*expected, "ckpt_000000001024"):
        assert text in message, (text, message)


def test_resume_of_a_checkpoint_without_stored_arguments(measured_run, tmp_path):
    # a checkpoint of an earlier version: no "args" block; its env arguments, hyperparameters,
    # seed and vehicles are restored all the same
    from capsule_env.agents.learning.training import prepare

    out = _copy_run(measured_run[0], tmp_path)
    meta_path = out / "checkpoints" / "ckpt_000000001024.json"
    meta = json.loads(meta_path.read_text())
    del meta["args"]
    meta_path.write_text(json.dumps(meta))
    plan = prepare(train.parse_args(["--resume", "auto", "--output-dir", str(out),
                                     "--total-timesteps", "2048"]))  # fmt: skip
    assert plan.env_kwargs["observation"] == "measured" and plan.num_envs == 4
    assert plan.args.seed == 3 and plan.hp["n_steps"] == 256


# ------------------------------------------------------- --resume of a finished run
def _folder_bytes(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}  # fmt: skip


def test_resume_of_a_finished_run_changes_nothing(ppo_run, tmp_path, capsys):
    out = _copy_run(ppo_run[0], tmp_path)
    before = _folder_bytes(out)
    assert len((out / "evaluations.jsonl").read_text().splitlines()) == 2
    summary = train.train(train.parse_args(["--resume", "auto", "--output-dir", str(out),
                                            "--no-progress"]))  # fmt: skip
    assert summary["num_timesteps"] == 2048 and not summary["interrupted"]
    assert "had finished at 2048 timesteps" in capsys.readouterr().out
    assert _folder_bytes(out) == before  # no evaluation appended, no file rewritten


def test_resume_after_a_kill_before_the_final_save_saves_it_once(ppo_run, tmp_path):
    # killed after the final evaluation was logged, before final_model was saved
    out = _copy_run(ppo_run[0], tmp_path)
    for path in out.glob("final_model.*"):
        path.unlink()
    lines = (out / "evaluations.jsonl").read_text()
    train.train(train.parse_args(["--resume", "auto", "--output-dir", str(out), "--no-progress"]))
    assert (out / "evaluations.jsonl").read_text() == lines
    final = SB3Policy.load(out / "final_model.zip")
    assert final.meta["num_timesteps"] == 2048 and final.name == "tiny-ppo-final"


def test_a_fresh_run_into_another_run_s_folder_is_refused(ppo_run, tiny_ppo_yml, tmp_path):
    # issue 40: the default runs/<algo>-seed<seed> run twice overwrote best_model with a worse
    # one and mixed both runs' checkpoints and evaluations.jsonl
    out = _copy_run(ppo_run[0], tmp_path)
    before = _folder_bytes(out)
    done = _run_cli(*fast_args(tiny_ppo_yml, out, "--total-timesteps", "256"))
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode != 0 and len(lines) == 1 and "Traceback" not in done.stderr
    assert f"--output-dir {out} holds another run's files" in lines[0]
    assert "--resume auto" in lines[0] and "another --output-dir" in lines[0]
    assert _folder_bytes(out) == before


def test_a_folder_killed_before_its_first_checkpoint_is_not_reused(tiny_ppo_yml, tmp_path):
    # a run stopped before its first checkpoint left its first evaluation and best model
    out = tmp_path / "killed"
    (out / "checkpoints").mkdir(parents=True)
    (out / "evaluations.jsonl").write_text('{"num_timesteps": 1024}\n')
    before = _folder_bytes(out)
    with pytest.raises(SystemExit) as stop:
        train.train(train.parse_args(fast_args(tiny_ppo_yml, out, "--total-timesteps", "256")))
    assert "no checkpoint to continue from" in str(stop.value.code)
    assert "--resume auto" not in str(stop.value.code)
    assert _folder_bytes(out) == before
    empty = tmp_path / "empty"
    (empty / "checkpoints").mkdir(parents=True)  # a folder of no run's files is fine
    (empty / "ppo.yml").write_text(tiny_ppo_yml.read_text())
    assert train.train(train.parse_args(fast_args(tiny_ppo_yml, empty, "--total-timesteps",
                                                  "256")))["num_timesteps"] == 1024  # fmt: skip


@pytest.mark.parametrize("seed", [str(2**32), "-1"])
def test_a_seed_out_of_range_stops_before_any_folder(tiny_ppo_yml, tmp_path, seed):
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as stop:
        train.train(train.parse_args(fast_args(tiny_ppo_yml, out, "--seed", seed)))
    assert str(stop.value.code) == f"train.py: error: --seed must be in 0..4294967295, got {seed}"
    assert not out.exists()


def test_a_run_is_compared_with_its_task_s_best_law_on_the_same_signals(
    tiny_ppo_yml, tmp_path, capsys
):
    # issue 40: every run printed the ideal-sensor skyhook-cont-biexp as its reference, also on
    # the measured-signal ride task, whose card names mpc-biexp-meas
    from capsule_env.tasks import task_named

    out = tmp_path / "run"
    train.train(train.parse_args(fast_args(tiny_ppo_yml, out, "--total-timesteps", "256",
                                           "--eval-freq", "0")))  # fmt: skip
    printed = capsys.readouterr().out
    best = task_named("CapsuleRide-v0").best_classical
    assert "references: passive Wk " in printed and f"; {best} Wk " in printed
    assert "skyhook-cont-biexp" not in printed
    refs = json.loads((out / "best_model.json").read_text())["eval"]["references"]
    assert set(refs) == {"passive", best}
    assert refs[best]["wk_rms_body_acc_m_s2"] < refs["passive"]["wk_rms_body_acc_m_s2"]


def _reads(env_kwargs: dict) -> tuple[str, bool]:
    """The signal set a policy (or a law, by its own env arguments) reads: the full state or
    measurable signals ('sensors' is a subset of 'measured'), and whether with a preview."""
    full = env_kwargs.get("observation") == "full_state"
    return ("full_state" if full else "measured"), int(env_kwargs.get("preview_points", 0)) > 0


def test_the_reference_law_reads_what_the_policy_reads(monkeypatch):
    # issue 40: every run was compared with the ideal-sensor skyhook-cont-biexp; then a run
    # with a preview other than the preview task's was compared with a law without one, and a
    # 'sensors' or 'full_state' run with the clipped LQR, not the best law on its signals
    from capsule_env.agents import classical_controllers
    from capsule_env.agents.controllers import mpc_solver

    from capsule_env.tasks import TASKS

    monkeypatch.setattr(mpc_solver, "solver_available", lambda *a: True)
    for task in TASKS:  # a task's own options: its card's law
        assert training.reference_law(dict(task.kwargs)) == task.best_classical
    laws = classical_controllers()
    results = json.loads((ROOT / "docs" / "figures" / "evaluation.json").read_text())
    for setting in ("sim", "hils"):
        wk = {n: c["wk_rms_body_acc_m_s2"]
              for n, c in results["settings"][setting]["controllers"].items() if n in laws}  # fmt: skip
        for observation in ("sensors", "measured", "full_state"):
            for points in (0, 8, 32):
                env = {"setting": setting, "observation": observation, "preview_points": points}
                name = training.reference_law(env)
                assert _reads(laws[name].env_kwargs) == _reads(env), (env, name)
                same = [n for n in wk if _reads(laws[n].env_kwargs) == _reads(env)]
                assert name == min(same, key=wk.get), (env, name)  # the best on those signals
    ride = {"setting": "hils", "observation": "measured", "speed_kmh": 600}
    assert training.reference_law({**ride, "preview_points": 16}) == "preview-mpc-biexp-meas"
    monkeypatch.setattr(mpc_solver, "solver_available", lambda *a: False)  # no mpc extra
    assert training.reference_law(ride) == "lqr-clipped-biexp-meas"
    assert training.reference_law({**ride, "preview_points": 32}) == "preview-lq-biexp-meas"
    assert training.reference_law({**ride, "observation": "full_state"}) == "lqr-clipped-biexp"


def test_a_checkpoint_continued_in_another_run_s_folder_is_refused(ppo_run, measured_run, tmp_path):
    # --resume of one run's checkpoint with another run's --output-dir wrote over that run
    ckpt = measured_run[0] / "checkpoints" / "ckpt_000000001024.zip"
    out = _copy_run(ppo_run[0], tmp_path)
    before = _folder_bytes(out)
    with pytest.raises(SystemExit) as stop:
        train.train(train.parse_args(["--resume", str(ckpt), "--output-dir", str(out)]))
    assert f"--output-dir {out} holds another run's files" in str(stop.value.code)
    assert _folder_bytes(out) == before
    fresh = tmp_path / "branch"  # a folder of its own: planned, and made only to train
    plan = training.prepare(train.parse_args(["--resume", str(ckpt), "--output-dir", str(fresh)]))
    assert plan.ckpt == ckpt and plan.output_dir == fresh and not fresh.exists()
