"""Issue 44, items 4-5: controllers' rollouts as Minari datasets, and offline baselines on them.

The independent facts: a dataset's rewards, observations and actions are what the same
controller gives when it is run again on the same seeds in the env that
``minari.load_dataset(...).recover_environment()`` builds from the stored spec (a single
Gymnasium env stepped here, not the vector env the recording used); the recovered env is the
registered task with the controller's options and the task's spaces; the oracle's actions are
its searched currents; bad input to the command writes nothing and says so in one line. Every
dataset lives under ``tmp_path`` (``--out``): ``HOME`` points to an empty folder for the module,
and nothing may appear in its ``.minari``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from conftest import DT, I_MAX, NO_SB3

DATASETS_EXTRA = "optional, in the datasets extra: pip install 'capsule-env[datasets]'"
minari = pytest.importorskip("minari", reason=f"minari is not installed ({DATASETS_EXTRA})")
pytest.importorskip("h5py", reason=f"h5py is not installed ({DATASETS_EXTRA})")

from capsule_env.agents.controllers.classical import make_controller  # noqa: E402

from capsule_env.datasets import load_dataset, minari_store, record_dataset  # noqa: E402
from capsule_env.datasets.__main__ import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TASK = "CapsuleRide-v0"
LENGTH_S = 0.5  # 100 control steps


@pytest.fixture(autouse=True)
def _no_home_minari(tmp_path, monkeypatch):
    """``HOME`` an empty folder and ``MINARI_DATASETS_PATH`` unset: a write to Minari's default
    root would land in ``HOME/.minari``, which must stay absent."""
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.delenv("MINARI_DATASETS_PATH", raising=False)
    yield
    assert not (home / ".minari").exists()
    assert "MINARI_DATASETS_PATH" not in os.environ


def _seed(dataset, episode) -> int:
    (meta,) = dataset.storage.get_episode_metadata([episode.id])
    return int(meta["seed"])


def _rerun(env, policy, seed: int, steps: int):
    """``policy`` on the single env seeded ``seed``: observations, actions, rewards."""
    obs, _ = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset()
    observations, actions, rewards = [obs], [], []
    for _ in range(steps):
        action, _ = policy.predict(obs[None])
        obs, reward, terminated, truncated, _ = env.step(action[0])
        observations.append(obs)
        actions.append(action[0])
        rewards.append(reward)
    return np.array(observations), np.array(actions), np.array(rewards)


@pytest.fixture(scope="module")
def mpc_root(tmp_path_factory):
    """Three 0.5 s episodes of the MPC on the ride task, seeds 7..9, through the command."""
    pytest.importorskip("daqp", reason="the MPC's QP solver (the mpc extra)")
    root = tmp_path_factory.mktemp("mpc") / "root"
    old = os.environ.pop("MINARI_DATASETS_PATH", None)
    assert main(["--task", TASK, "--controller", "mpc-biexp-meas", "--episodes", "3", "--seed",
                 "7", "--out", str(root), "--episode-length", str(LENGTH_S)]) == 0  # fmt: skip
    assert old is None and "MINARI_DATASETS_PATH" not in os.environ
    return root


MPC_ID = f"capsule_env/{TASK}/mpc-biexp-meas-v0"


def test_mpc_dataset_is_a_rerun_bit_for_bit_in_the_recovered_env(mpc_root):
    dataset = load_dataset(mpc_root, MPC_ID)
    assert dataset.total_episodes == 3 and dataset.total_steps == 300
    env = dataset.recover_environment()
    seeds = []
    for episode in dataset.iterate_episodes():
        seeds.append(_seed(dataset, episode))
        obs, actions, rewards = _rerun(env, make_controller("mpc-biexp-meas"), seeds[-1], 100)
        assert np.array_equal(episode.rewards, rewards)
        assert np.array_equal(episode.observations, obs)
        assert np.array_equal(episode.actions, actions)
        assert not episode.terminations.any() and episode.truncations[-1]
    assert seeds == [7, 8, 9]


def test_the_recovered_env_is_the_task_with_its_spaces(mpc_root):
    with minari_store.datasets_root(mpc_root):  # Minari's own loader, as a user calls it
        dataset = minari.load_dataset(MPC_ID)
    task = gym.make(TASK)
    env, eval_env = dataset.recover_environment(), dataset.recover_environment(eval_env=True)
    for got in (env, eval_env):
        assert got.spec.id == TASK
        assert got.observation_space == task.observation_space
        assert got.action_space == task.action_space
        registered = gym.spec(TASK).kwargs
        assert {k: got.spec.kwargs[k] for k in registered} == registered
    assert env.spec.kwargs["episode_length_s"] == LENGTH_S
    assert env.spec.kwargs["guideway_seed"] == 0  # named: the training bank
    assert eval_env.spec.kwargs["guideway_seed"] == 2026  # evaluate.py's bank
    meta = dataset.storage.metadata["capsule_env"]
    assert meta["controller"]["name"] == "mpc-biexp-meas" and meta["seeds"] == [7, 8, 9]
    assert meta["observation_names"][0].endswith("m_s2") and len(meta["observation_names"]) == 9


def test_the_infos_hold_the_env_signals_with_the_reset_first(mpc_root):
    dataset = load_dataset(mpc_root, MPC_ID)
    episode = next(iter(dataset.iterate_episodes()))
    env = gym.make(TASK, **dataset.recover_environment().spec.kwargs)
    _, info = env.reset(seed=7)
    acc = episode.infos["car_body_acceleration_m_s2"]
    assert acc.shape == (101,) and acc[0] == info["car_body_acceleration_m_s2"]
    ctrl = make_controller("mpc-biexp-meas")
    ctrl.reset()
    action, _ = ctrl.predict(episode.observations[0][None])
    _, _, _, _, info = env.step(action[0])
    assert acc[1] == info["car_body_acceleration_m_s2"]


def test_an_episode_ends_at_its_bump_stop_as_the_single_env_ends_it():
    """With a 4 mm bump stop the 0 A damper hits it within 0.5 s: each episode is cut at its
    own termination step, where the single env seeded alike terminates too."""
    from capsule_env.datasets.rollouts import record_episodes

    law = make_controller("mr-0A")
    kwargs = {**gym.spec(TASK).kwargs, **law.env_kwargs, "stroke_limit_m": 0.004}
    episodes = record_episodes(law, kwargs, [0, 1, 2], LENGTH_S)
    env = gym.make(TASK, episode_length_s=LENGTH_S, **kwargs)
    for seed, episode in zip([0, 1, 2], episodes):
        env.reset(seed=seed)
        rewards, terminated = [], False
        while not terminated:
            _, reward, terminated, truncated, info = env.step(episode.actions[0])
            rewards.append(reward)
            assert not truncated
        assert np.array_equal(episode.rewards, rewards) and episode.steps < 100
        assert episode.terminations[-1] and not episode.terminations[:-1].any()
        assert episode.observations.shape == (episode.steps + 1, 9)
        assert (
            abs(episode.infos["stroke_m"][-1]) > 0.004
            and len(episode.infos["stroke_m"]) == episode.steps + 1
        )


@pytest.mark.rl
def test_a_learned_policy_reruns_to_float32_rounding(tmp_path):
    """A learned policy's network acts on a batch (all episodes at once) when recording and on
    one observation when re-run: torch's kernels round differently (measured: actions to 5e-7),
    so the re-run agrees to 2e-6 in the actions and 1e-5 relative in the rewards, not bit for
    bit."""
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, load_policy

    root = tmp_path / "ppo"
    folder, ident = record_dataset(TASK, "ppo-measured", 2, 5, root, episode_length_s=LENGTH_S)
    assert folder == root.absolute() / ident
    dataset = load_dataset(root, ident)
    env = dataset.recover_environment()
    policy = load_policy(PRETRAINED_DIR / "ppo-measured.zip")
    for episode in dataset.iterate_episodes():
        _, actions, rewards = _rerun(env, policy, _seed(dataset, episode), 100)
        np.testing.assert_allclose(episode.actions, actions, rtol=0, atol=2e-6)
        np.testing.assert_allclose(episode.rewards, rewards, rtol=1e-5, atol=1e-9)
    assert dataset.storage.metadata["capsule_env"]["controller"]["kind"] == "learned"


def test_the_oracle_records_its_applied_currents(tmp_path):
    """The oracle's actions are its searched currents ``u`` as ``2 u / i_max - 1`` (float32);
    replayed in the recovered env (current mode, no delay) they give the dataset's rewards bit
    for bit and the search's own Wk."""
    from capsule_env import metrics
    from capsule_env.oracle import clairvoyant_bound

    search = {"max_iter": 4, "restarts": 0, "starts": ("zero",)}
    _, ident = record_dataset(TASK, "oracle", 2, 3, tmp_path / "o", episode_length_s=LENGTH_S,
                              oracle_search=search)  # fmt: skip
    dataset = load_dataset(tmp_path / "o", ident)
    env = dataset.recover_environment()
    assert env.spec.kwargs["action_mode"] == "current"
    assert env.spec.kwargs["control_delay_steps"] == 0
    direct = clairvoyant_bound({**gym.spec(TASK).kwargs, "guideway_seed": 0}, [3, 4], LENGTH_S,
                               **search)  # fmt: skip
    for k, episode in enumerate(dataset.iterate_episodes()):
        want = (2.0 * direct.currents_a[k] / I_MAX - 1.0).astype(np.float32)
        assert np.array_equal(episode.actions[:, 0], want)
        env.reset(seed=3 + k)
        rewards = [env.step(a)[1] for a in episode.actions]
        assert np.array_equal(episode.rewards, np.array(rewards))
        wk = metrics.wk_weighted_rms(episode.infos["car_body_acceleration_m_s2"][1:], DT)
        assert wk == pytest.approx(direct.wk_rms_body_acc_m_s2[k], rel=1e-6)
    assert "applied-current" in dataset.storage.metadata["capsule_env"]["action"]


def _only_line(text: str) -> str:
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    assert "Traceback" not in text
    return lines[0]


@pytest.mark.parametrize(
    "change, needle",
    [
        ({"--task": "CapsuleRide-v9"}, "--task must be one of"),
        ({"--controller": "skyhook-nope"}, "--controller must be"),
        ({"--controller": "lqr-sched-biexp-meas"}, "speed_profile"),
        ({"--episodes": "0"}, "--episodes must be an integer >= 1"),
        ({"--seed": "-1"}, "--seed must be an integer in 0.."),
        ({"--name": "a/b"}, "--name must be"),
        ({"--episode-length": "0"}, "episode_length_s"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, change, needle):
    args = {"--task": TASK, "--controller": "passive", "--episodes": "2", "--seed": "0",
            "--out": str(tmp_path / "out"), "--episode-length": str(LENGTH_S), **change}  # fmt: skip
    assert main([x for kv in args.items() for x in kv]) == 1
    line = _only_line(capsys.readouterr().err)
    assert line.startswith("capsule-datasets: error: ") and needle in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["home"]


def test_an_existing_non_empty_out_or_a_file_is_refused(tmp_path, capsys):
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("mine")
    afile = tmp_path / "afile"
    afile.write_text("x")
    for out, needle in ((full, "is not empty"), (afile, "is a file")):
        code = main(["--task", TASK, "--controller", "passive", "--episodes", "1", "--out",
                     str(out), "--episode-length", str(LENGTH_S)])  # fmt: skip
        assert code == 1 and needle in _only_line(capsys.readouterr().err)
    assert [p.name for p in full.iterdir()] == ["keep.txt"] and afile.read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "full", "home"]


def test_an_empty_out_is_filled_and_the_command_runs_as_a_process(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()

    def cmd(controller: str, out: Path) -> list[str]:
        return [
            sys.executable,
            "-m",
            "capsule_env.datasets",
            "--task",
            TASK,
            "--controller",
            controller,
            "--episodes",
            "1",
            "--out",
            str(out),
            "--episode-length",
            "0.5",
        ]

    done = subprocess.run(cmd("passive", empty), capture_output=True, text=True, cwd=ROOT,
                          timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == [str(empty / f"capsule_env/{TASK}/passive-v0"),
                                   f"capsule_env/{TASK}/passive-v0"]  # fmt: skip
    assert load_dataset(empty, f"capsule_env/{TASK}/passive-v0").total_steps == 100
    bad = subprocess.run(cmd("nope", tmp_path / "x"), capture_output=True, text=True, cwd=ROOT,
                         timeout=300)  # fmt: skip
    assert bad.returncode == 1 and "--controller must be" in _only_line(bad.stderr)
    assert not (tmp_path / "x").exists()


def test_a_failed_write_leaves_no_dataset_and_no_staging(tmp_path, monkeypatch):
    def fail(*args, **kwargs):
        (Path(os.environ["MINARI_DATASETS_PATH"]) / "partial.hdf5").write_bytes(b"half")
        raise OSError("disk full")

    monkeypatch.setattr(minari_store, "_create", fail)
    with pytest.raises(OSError, match="disk full"):
        record_dataset(TASK, "passive", 1, 0, tmp_path / "out", episode_length_s=LENGTH_S)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["home"]


# ----------------------------------------------------------------------------- offline baselines
def test_the_transitions_follow_each_episode(mpc_root):
    from capsule_env.datasets.offline_eval import transitions

    data = transitions(load_dataset(mpc_root, MPC_ID))
    assert data.observations.shape == (300, 9) and data.actions.shape == (300, 1)
    ends = np.flatnonzero(data.truncations)
    assert list(ends) == [99, 199, 299] and not data.terminations.any()
    inside = np.setdiff1d(np.arange(299), ends)
    assert np.array_equal(data.next_observations[inside], data.observations[inside + 1])


@pytest.mark.rl
def test_behaviour_cloning_fits_the_demonstrators_actions(mpc_root):
    """After 400 steps the network's squared error on the dataset is a small part of the
    actions' own variance (what predicting their mean would leave)."""
    torch = pytest.importorskip("torch", reason=NO_SB3)
    from capsule_env.datasets.bc import Args, train_bc
    from capsule_env.datasets.offline_eval import transitions

    data = transitions(load_dataset(mpc_root, MPC_ID))
    net, losses = train_bc(data, Args(gradient_steps=400), seed=0)
    with torch.no_grad():
        predicted = net(torch.as_tensor(data.observations)).numpy()
    assert np.mean((predicted - data.actions) ** 2) < 0.2 * np.var(data.actions)
    assert np.isfinite(losses["mse"]) and torch.get_num_threads() == 1


@pytest.mark.rl
def test_an_offline_run_evaluates_on_the_evaluation_bank_against_the_demonstrator(
    mpc_root, tmp_path, capsys
):
    pytest.importorskip("torch", reason=NO_SB3)
    pytest.importorskip("rliable", reason=NO_SB3)
    from capsule_env.datasets.bc import main as bc_main

    out = tmp_path / "bc.json"
    code = bc_main(["--dataset-root", str(mpc_root), "--seeds", "2", "--eval-episodes", "2",
                    "--eval-episode-length-s", "0.5", "--gradient-steps", "50", "--json",
                    str(out)])  # fmt: skip
    assert code == 0
    import json

    results = json.loads(out.read_text())
    assert results["eval_env_kwargs"]["guideway_seed"] == 2026
    assert results["dataset_id"] == MPC_ID and results["transitions"] == 300
    assert set(results["references_wk_m_s2"]) == {"passive", "mpc-biexp-meas"}
    assert [len(r["wk_per_episode_m_s2"]) for r in results["runs"]] == [2, 2]
    ratio = results["ratio_to_mpc-biexp-meas_both"]
    assert ratio["low"] <= ratio["iqm"] <= ratio["high"]
    assert json.loads(capsys.readouterr().out) == results


@pytest.mark.rl
def test_td3bc_trains_its_actor(mpc_root):
    torch = pytest.importorskip("torch", reason=NO_SB3)
    pytest.importorskip("torchrl", reason="TorchRL is not installed (the dev extra)")
    from capsule_env.datasets.offline_eval import transitions
    from capsule_env.datasets.td3bc import Args, train_td3bc

    data = transitions(load_dataset(mpc_root, MPC_ID))
    net, _ = train_td3bc(data, Args(gradient_steps=0), seed=0)
    trained, losses = train_td3bc(data, Args(gradient_steps=40), seed=0)
    x = torch.as_tensor(data.observations[:50])
    with torch.no_grad():
        assert not torch.equal(net(x), trained(x))
    assert all(np.isfinite(v) for v in losses.values())


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--seeds", "1"], "--seeds and --eval-episodes must be >= 2"),
        (["--gradient-steps", "0"], "--gradient-steps must be >= 1"),
        (["--learning-rate", "nan"], "--learning-rate must be in"),
    ],
)
def test_offline_bad_input_is_one_line(mpc_root, capsys, args, needle):
    from capsule_env.datasets.bc import main as bc_main

    assert bc_main(["--dataset-root", str(mpc_root), *args]) == 1
    line = _only_line(capsys.readouterr().err)
    assert line.startswith("python -m capsule_env.datasets.bc: error: ") and needle in line


def test_offline_without_a_dataset_is_one_line(tmp_path, capsys):
    from capsule_env.datasets.bc import main as bc_main

    assert bc_main(["--dataset-root", str(tmp_path / "none")]) == 1
    assert "is not a folder" in _only_line(capsys.readouterr().err)
    (tmp_path / "empty").mkdir()
    assert bc_main(["--dataset-root", str(tmp_path / "empty")]) == 1
    assert "holds 0 datasets" in _only_line(capsys.readouterr().err)


def test_the_howto_page_quotes_its_result_files():
    """docs/howto-datasets.md's table and claims are the --json files in docs/figures/."""
    import json

    page = " ".join((ROOT / "docs" / "howto-datasets.md").read_text().split())
    figures = ROOT / "docs" / "figures"
    bc = json.loads((figures / "offline-bc-CapsuleRide-v0.json").read_text())
    td3 = json.loads((figures / "offline-td3bc-CapsuleRide-v0.json").read_text())
    refs = bc["references_wk_m_s2"]
    assert refs == td3["references_wk_m_s2"]
    assert f"| passive | {refs['passive']:.4f} |" in page
    assert f"| `mpc-biexp-meas` (the demonstrator) | {refs['mpc-biexp-meas']:.4f} | 1 |" in page
    for results, digits in ((bc, 3), (td3, 2)):
        wk = [run["wk_rms_body_acc_m_s2"] for run in results["runs"]]
        assert f"(per seed {', '.join(f'{w:.4f}' for w in wk)}) | {np.mean(wk):.4f} (mean)" in page
        both, seeds = (results[f"ratio_to_mpc-biexp-meas_{k}"] for k in ("both", "seeds"))
        text = f"{both['iqm']:.{digits}f}"
        text = f"**{text}**" if results is bc else text
        assert (f"{text} [{both['low']:.{digits}f}, {both['high']:.{digits}f}]; seeds alone "
                f"[{seeds['low']:.{digits}f}, {seeds['high']:.{digits}f}]") in page  # fmt: skip
        assert results["evaluation"]["eval_episodes"] == 10 and len(results["runs"]) == 5
    ratio = bc["ratio_to_mpc-biexp-meas_both"]
    assert (f"rides {100 * (ratio['iqm'] - 1):.1f} % worse than the MPC it clones** (interval "
            f"{100 * (ratio['low'] - 1):.1f} % to {100 * (ratio['high'] - 1):.1f} %)") in page  # fmt: skip
    wk_bc = [run["wk_rms_body_acc_m_s2"] for run in bc["runs"]]
    assert all(refs["mpc-biexp-meas"] < w < refs["passive"] for w in wk_bc)
    wk_td3 = [run["wk_rms_body_acc_m_s2"] for run in td3["runs"]]
    assert np.mean(wk_td3) > refs["passive"]
    assert f"(mean {np.mean(wk_td3):.4f} against {refs['passive']:.4f})" in page
    distances = [run["final_losses"]["bc"] for run in td3["runs"]]
    assert f"{min(distances):.2f} to {max(distances):.2f}" in page
    assert bc["transitions"] == 40_000
