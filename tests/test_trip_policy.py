"""The trip task's policy: ``train.py --task``, which shipped policies an evaluation adds
(:func:`fits_condition`), and the shipped ``ppo-trip`` on ``CapsuleTrip-v0`` (loads, runs, its
digests verify, it is in that task's default evaluation and not in the paper's)."""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from conftest import NO_SB3, NO_YAML

pytest.importorskip("stable_baselines3", reason=NO_SB3)
pytest.importorskip("yaml", reason=NO_YAML)

from capsule_env.agents.learning import train
from capsule_env.agents.learning.run_args import restore_arguments  # noqa: E402
from capsule_env.agents.learning.sb3_policy import (  # noqa: E402
    PRETRAINED_DIR,
    SB3Policy,
    fits_condition,
    shipped_policy_paths,
)
from capsule_env.agents.learning.training import prepare  # noqa: E402

import capsule_env  # noqa: E402, F401  (registers the tasks)
from capsule_env.evaluation import evaluate  # noqa: E402
from capsule_env.tasks import task_named  # noqa: E402

pytestmark = pytest.mark.rl

TRIP = "CapsuleTrip-v0"
#: CapsuleTrip-v0's options, written out by hand (capsule_env/tasks.py registers them).
TRIP_OPTIONS = {"setting": "hils", "observation": "measured", "levitation": "eds",
                "speed_profile": "trip", "spans": "continuous",
                "payload_range": (-0.3, 0.4)}  # fmt: skip
PPO_TRIP = PRETRAINED_DIR / "ppo-trip.zip"


# ----------------------------------------------------------------------------- train.py --task
def test_train_task_reads_the_registered_options(tmp_path):
    plan = prepare(train.parse_args(["--task", TRIP, "--output-dir", str(tmp_path)]))
    # the task's options over hyperparams/ppo.yml's (the ride task's, action_mode force)
    assert plan.env_kwargs == {**TRIP_OPTIONS, "action_mode": "force"}
    assert plan.args.task == TRIP
    # --env over the task's
    argv = ["--task", TRIP, "--env", "payload_range=(0.0, 0.1)", "--output-dir", str(tmp_path)]
    plan = prepare(train.parse_args(argv))
    assert plan.env_kwargs["payload_range"] == (0.0, 0.1)
    assert plan.env_kwargs["levitation"] == "eds"
    # without --task: the file's options (the ride task's since issue 30), no envelope
    plan = prepare(train.parse_args(["--output-dir", str(tmp_path)]))
    assert plan.env_kwargs["observation"] == "measured" and "levitation" not in plan.env_kwargs


def test_train_bad_task_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr(train, "make_env", lambda *a, **k: pytest.fail("training started"))
    argv = ["--task", "CapsuleTrip-v9", "--output-dir", str(tmp_path), "--no-progress"]
    with pytest.raises(SystemExit) as info:
        train.train(train.parse_args(argv))
    message = str(info.value.code)
    assert message.startswith("train.py: error: --task must be one of CapsuleSuspension-v0")
    assert "'CapsuleTrip-v9'" in message and "\n" not in message


def test_resume_restores_the_task_and_refuses_another(tmp_path):
    meta = {"args": {"algo": "ppo", "seed": 0, "task": TRIP}}
    ckpt = tmp_path / "ckpt_000000001024.zip"
    args = restore_arguments(train.parse_args(["--resume", "auto"]), meta, ckpt)
    assert args.task == TRIP
    given = train.parse_args(["--resume", "auto", "--task", "CapsuleRide-v0"])
    with pytest.raises(ValueError, match="--task 'CapsuleRide-v0' differs from the run's"):
        restore_arguments(given, meta, ckpt)


# ----------------------------------------------------------------------------- which policies
MEASURED = {"setting": "hils", "action_mode": "force", "observation": "measured"}
TRIP_TRAINED = {**TRIP_OPTIONS, "action_mode": "force", "payload_range": [-0.3, 0.4]}


@pytest.mark.parametrize(
    ("own", "condition", "fits"),
    [
        (MEASURED, {}, True),  # the paper's env: what it was trained in
        (MEASURED, {"speed_kmh": 400}, True),  # another speed: same physics options, columns
        (MEASURED, TRIP_OPTIONS, False),  # the trip gives two more observation columns
        (TRIP_TRAINED, TRIP_OPTIONS, True),  # its task (a JSON list equals the tuple)
        (TRIP_TRAINED, {}, False),  # fixed levitation, constant speed: not its physics
        (TRIP_TRAINED, {"speed_kmh": 400}, False),
        (TRIP_TRAINED, {**TRIP_OPTIONS, "payload_range": (0.0, 0.1)}, False),
        (TRIP_TRAINED, {**TRIP_OPTIONS, "setting": "sim"}, True),  # the setting is chosen
        ({**MEASURED, "preview_points": 32}, {}, True),  # what it reads is its own
    ],
)
def test_fits_condition(own, condition, fits):
    assert fits_condition(own, condition) is fits


# ----------------------------------------------------------------------------- ppo-trip
def test_ppo_trip_is_shipped_with_verified_digests(tmp_path):
    meta = json.loads(PPO_TRIP.with_suffix(".json").read_text())
    assert meta["name"] == "ppo-trip" and "validation" in meta["selection"]
    env_kwargs = {k: v for k, v in meta["env_kwargs"].items() if k != "action_mode"}
    assert env_kwargs == json.loads(json.dumps(TRIP_OPTIONS))
    assert (PRETRAINED_DIR / f"{task_named(TRIP).shipped_policy}.zip").is_file()
    # a copy with one byte of the model changed is refused by its recorded SHA-256
    for suffix in (".zip", ".vecnormalize.pkl", ".json"):
        shutil.copy(PRETRAINED_DIR / f"ppo-trip{suffix}", tmp_path / f"ppo-trip{suffix}")
    SB3Policy.load(tmp_path / "ppo-trip.zip")
    blob = bytearray((tmp_path / "ppo-trip.zip").read_bytes())
    blob[len(blob) // 2] ^= 0xFF
    (tmp_path / "ppo-trip.zip").write_bytes(bytes(blob))
    with pytest.raises(ValueError, match="does not match ppo-trip.json"):
        SB3Policy.load(tmp_path / "ppo-trip.zip")


def test_ppo_trip_runs_on_the_trip_task():
    policy = SB3Policy.load(PPO_TRIP)
    envs = gym.make_vec(TRIP, num_envs=4, vectorization_mode="vector_entry_point",
                        action_mode=policy.env_kwargs["action_mode"])  # fmt: skip
    obs, _ = envs.reset(seed=3)
    speeds = []
    actions = []
    for _ in range(100):
        action, _ = policy.predict(obs, deterministic=True)
        assert action.shape == (4, 1) and np.all(np.abs(action) <= 1.0)
        actions.append(action)
        obs, reward, terminated, truncated, _ = envs.step(action)
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward)) and not terminated.any()
        speeds.append(obs[:, -2])
    envs.close()
    assert np.std(np.concatenate(actions)) > 0.05  # it acts on its vehicles
    assert np.ptp(np.ravel(speeds)) > 1.0  # trips: four vehicles at different speeds (m/s)


TRIP_POLICIES = ["ppo-trip", "residual-ppo-mpc-trip"]  # trained on the trip task


def test_the_trip_policies_in_the_trip_tasks_evaluation_only():
    names = {Path(p).stem for p in shipped_policy_paths(task_named(TRIP).kwargs)}
    assert names == set(TRIP_POLICIES)
    paper = {Path(p).stem for p in shipped_policy_paths({})}
    assert not paper & names and {"ppo-hils", "ppo-measured", "ppo-preview"} <= paper
    ctrls = evaluate.build_controllers(["passive"], [], shipped=True,
                                       env_kwargs=task_named(TRIP).kwargs)  # fmt: skip
    # the residual on the MPC needs the MPC's QP solver (the mpc extra): left out without it
    runs_mpc = importlib.util.find_spec("daqp") is not None
    assert list(ctrls) == ["passive", *TRIP_POLICIES[: 2 if runs_mpc else 1]]
    assert not set(TRIP_POLICIES) & set(evaluate.build_controllers(["passive"], [], shipped=True))


def test_the_shipped_residual_on_the_trip_mpc_is_the_mpc_plus_a_bounded_correction():
    """residual-ppo-mpc-trip: the MPC's request plus at most half the action range (its
    scale), checked against an independent MPC fed the same observations, on four trips; it
    corrects (the requests differ) and stays within the damper's range."""
    pytest.importorskip("daqp", reason="the MPC's QP solver (the mpc extra)")
    from capsule_env.agents.controllers.classical import make_controller
    from capsule_env.agents.learning.residual import ResidualPolicy
    from capsule_env.agents.learning.sb3_policy import load_policy

    policy = load_policy(PRETRAINED_DIR / "residual-ppo-mpc-trip.zip")
    assert isinstance(policy, ResidualPolicy) and policy.meta["residual"]["law"] == "mpc-biexp-meas"
    assert policy.scale == 0.5 and task_named(TRIP).shipped_policy == "residual-ppo-mpc-trip"
    law = make_controller("mpc-biexp-meas")  # the same law, its own instance
    envs = gym.make_vec(TRIP, num_envs=4, vectorization_mode="vector_entry_point",
                        action_mode=policy.env_kwargs["action_mode"])  # fmt: skip
    obs, _ = envs.reset(seed=5)
    start = np.ones(4, dtype=bool)
    gaps = []
    for _ in range(100):
        action, _ = policy.predict(obs, episode_start=start, deterministic=True)
        base, _ = law.predict(obs, episode_start=start, deterministic=True)
        assert np.all(np.abs(action) <= 1.0)
        gaps.append(np.abs(action - base))
        obs, _, terminated, truncated, _ = envs.step(action)
        assert np.all(np.isfinite(obs)) and not terminated.any()
        start = np.zeros(4, dtype=bool)
    envs.close()
    gaps = np.concatenate(gaps)
    assert gaps.max() <= 0.5 + 1e-6  # |clip(b + 0.5 r) - b| <= 0.5 |r| <= 0.5 for b in [-1, 1]
    assert gaps.mean() > 1e-3  # it corrects the MPC
