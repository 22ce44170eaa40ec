"""Review of the offline-RL path (helper 49): the recording's guideway bank named in the
dataset, the offline baselines judged on the evaluation bank whatever the dataset's evaluation
env names (and never trained on a held-out bank), their options checked before any training,
their help, and ``--out`` refused before the run where no folder can be made.

The independent facts: the guideway a recorded episode rode is the one ``gym.make`` gives with
the training bank named; the passive reference of an offline run is what
:func:`~capsule_env.evaluation.episodes.run_episodes` gives on the evaluation bank.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from conftest import NO_SB3

minari = pytest.importorskip("minari", reason="minari is not installed (the datasets extra)")
pytest.importorskip("h5py", reason="h5py is not installed (the datasets extra)")

from capsule_env.agents.controllers.classical import make_controller  # noqa: E402
from test_datasets import _no_home_minari, _only_line  # noqa: E402, F401  (HOME's .minari empty)

from capsule_env.datasets import load_dataset, minari_store, record_dataset  # noqa: E402
from capsule_env.datasets.rollouts import record_episodes  # noqa: E402

TASK = "CapsuleRide-v0"
LENGTH_S = 0.5
SHORT = ["--seeds", "2", "--eval-episodes", "2", "--eval-episode-length-s", str(LENGTH_S),
         "--gradient-steps", "1"]  # fmt: skip


def _foreign(root: Path, **env_kwargs) -> str:
    """A dataset written with Minari's own writer, no evaluation env named (Minari then uses
    the recording env): two passive episodes in ``gym.make(TASK, **env_kwargs)``."""
    env = gym.make(TASK, episode_length_s=LENGTH_S, **env_kwargs)
    options = {k: v for k, v in env.spec.kwargs.items() if k != "episode_length_s"}
    episodes = record_episodes(make_controller("passive"), options, [3, 4], LENGTH_S)
    ident = "mine/ride-v0"
    with minari_store.datasets_root(root), warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # Minari asks for an author, an eval env
        minari.create_dataset_from_buffers(ident, minari_store._buffers(episodes), env=env,
                                           algorithm_name="passive")  # fmt: skip
    return ident


def test_the_recording_bank_is_named_and_is_the_one_ridden(tmp_path):
    folder, ident = record_dataset(TASK, "passive", 1, 5, tmp_path / "out",
                                   episode_length_s=LENGTH_S)  # fmt: skip
    dataset = load_dataset(tmp_path / "out", ident)
    spec = dataset.recover_environment().spec
    assert spec.kwargs["guideway_seed"] == 0
    assert dataset.storage.metadata["capsule_env"]["env_kwargs"]["guideway_seed"] == 0
    ridden = next(iter(dataset.iterate_episodes())).infos["guideway_elevation_m"][0]
    for bank, same in ((0, True), (2026, False)):
        _, info = gym.make(TASK, guideway_seed=bank, episode_length_s=LENGTH_S).reset(seed=5)
        assert bool(info["guideway_elevation_m"] == ridden) is same


@pytest.mark.rl
def test_an_offline_run_is_judged_on_the_evaluation_bank_without_an_eval_env(tmp_path):
    """Minari's evaluation env is then the recording env, on the training bank it names."""
    pytest.importorskip("torch", reason=NO_SB3)
    pytest.importorskip("rliable", reason=NO_SB3)
    from capsule_env.datasets.bc import main as bc_main
    from capsule_env.evaluation.episodes import run_episodes

    _foreign(tmp_path / "root", guideway_seed=0)  # the training bank named, as recorded here
    out = tmp_path / "bc.json"
    assert bc_main(["--dataset-root", str(tmp_path / "root"), *SHORT, "--json", str(out)]) == 0
    results = json.loads(out.read_text())
    passive = make_controller("passive")
    roll = run_episodes(passive, {"setting": "hils", "observation": "measured",
                                  "guideway_seed": 2026, **passive.env_kwargs}, 2, 1000,
                        LENGTH_S)  # fmt: skip
    from capsule_env import metrics

    wk = metrics.wk_weighted_rms(roll.signals["car_body_acceleration_m_s2"], roll.dt_s)
    assert np.allclose(results["references_wk_per_episode_m_s2"]["passive"], wk, rtol=0, atol=0)
    assert results["eval_env_kwargs"]["guideway_seed"] == 2026


@pytest.mark.parametrize("bank, name", [(2026, "evaluation"), (7, "validation"),
                                        (11, "selection")])  # fmt: skip
def test_a_dataset_recorded_on_a_held_out_bank_is_refused(tmp_path, capsys, monkeypatch, bank,
                                                          name):  # fmt: skip
    from capsule_env.datasets import bc

    monkeypatch.setattr(bc, "train_bc", _not_reached)
    _foreign(tmp_path / "root", guideway_seed=bank)
    out = tmp_path / "bc.json"
    assert bc.main(["--dataset-root", str(tmp_path / "root"), *SHORT, "--json", str(out)]) == 1
    line = _only_line(capsys.readouterr().err)
    assert f"{name} guideway bank (guideway_seed={bank})" in line
    assert not out.exists()


def _not_reached(*args, **kwargs):
    raise AssertionError("ran before the input was checked")


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--eval-seed", str(2**63 - 1)], "--eval-seed must be in 0.."),
        (["--first-seed", str(2**63)], "--first-seed must be in 0.."),
        (["--eval-episode-length-s", "0.001"], "--eval-episode-length-s"),
        (["--eval-episodes", str(10**9)], "--eval-episodes / --eval-episode-length-s on the"),
    ],
)
def test_the_evaluation_options_are_checked_before_training(tmp_path, capsys, monkeypatch, args,
                                                            needle):  # fmt: skip
    from capsule_env.datasets import bc

    monkeypatch.setattr(bc, "train_bc", _not_reached)
    _foreign(tmp_path / "root")
    assert bc.main(["--dataset-root", str(tmp_path / "root"), *SHORT, *args]) == 1
    assert needle in _only_line(capsys.readouterr().err)


def test_the_help_gives_each_default_once(capsys):
    from capsule_env.datasets.bc import main as bc_main

    with pytest.raises(SystemExit) as stop:
        bc_main(["--help"])
    assert stop.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "resamples them) (default: 5)" in text
    assert "(default: 5) (default: 5)" not in text


def test_td3bc_without_torchrl_names_what_installs_it(monkeypatch, capsys):
    from capsule_env.datasets.td3bc import main as td3bc_main

    monkeypatch.setitem(sys.modules, "torchrl", None)  # import torchrl raises ImportError
    assert td3bc_main(["--dataset-root", "anything"]) == 1
    line = _only_line(capsys.readouterr().err)
    assert "torchrl>=0.14" in line and "capsule-env[datasets]" not in line


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_an_out_where_no_folder_can_be_made_is_refused_before_the_run(capsys, monkeypatch):
    """``/proc`` takes no new folder, even for root, whose permission bits allow it."""
    from capsule_env.datasets import record
    from capsule_env.datasets.__main__ import main

    monkeypatch.setattr(record, "record_episodes", _not_reached)
    out = "/proc/capsule-env-review-49/root"
    assert main(["--task", TASK, "--controller", "passive", "--out", out]) == 1
    assert "--out '/proc/capsule-env-review-49/root'" in _only_line(capsys.readouterr().err)
    assert not Path(out).parent.exists()


def test_ctrl_c_is_one_line_and_leaves_nothing(tmp_path, capsys, monkeypatch):
    from capsule_env.datasets import record
    from capsule_env.datasets.__main__ import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(record, "record_episodes", interrupted)
    out = tmp_path / "out"
    assert main(["--task", TASK, "--controller", "passive", "--out", str(out)]) == 130
    assert "interrupted" in _only_line(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["home"]


STOPPED_IN_THE_WRITE = """
import os, signal, sys
from pathlib import Path
from capsule_env.datasets import minari_store
from capsule_env.datasets.__main__ import main

def stopped(*args, **kwargs):  # a job scheduler's SIGTERM while Minari writes
    (Path(os.environ["MINARI_DATASETS_PATH"]) / "partial.hdf5").write_bytes(b"half")
    os.kill(os.getpid(), signal.SIGTERM)

minari_store._create = stopped
sys.exit(main(["--task", "CapsuleRide-v0", "--controller", "passive", "--episodes", "1",
               "--episode-length", "0.5", "--out", sys.argv[1]]))
"""


def test_sigterm_in_the_write_leaves_no_staging_folder(tmp_path):
    import subprocess

    work = tmp_path / "work"
    work.mkdir()
    run = subprocess.run([sys.executable, "-c", STOPPED_IN_THE_WRITE, str(work / "out")],
                         capture_output=True, text=True, timeout=300)  # fmt: skip
    assert run.returncode == 130, run.stderr
    assert "interrupted" in _only_line(run.stderr)
    assert list(work.iterdir()) == []


def test_ctrl_c_in_an_offline_run_is_one_line(tmp_path, capsys, monkeypatch):
    from capsule_env.datasets import bc

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(bc, "train_bc", interrupted)
    _foreign(tmp_path / "root")
    out = tmp_path / "bc.json"
    assert bc.main(["--dataset-root", str(tmp_path / "root"), *SHORT, "--json", str(out)]) == 130
    assert "interrupted" in _only_line(capsys.readouterr().err)
    assert not out.exists()


def test_a_recording_larger_than_the_memory_is_refused_before_the_run(tmp_path, capsys,
                                                                      monkeypatch):  # fmt: skip
    """2000 episodes of 10 s hold about 1.5 GiB until the write (0.8 MB each, measured in
    docs/howto-datasets.md): refused where 1 GiB is available, before any episode runs."""
    from capsule_env.datasets import record
    from capsule_env.datasets.__main__ import main

    monkeypatch.setattr(record, "record_episodes", _not_reached)
    monkeypatch.setattr(record, "available_memory_bytes", lambda: 2**30, raising=False)
    out = tmp_path / "out"
    args = ["--task", TASK, "--controller", "passive", "--out", str(out), "--episodes"]
    assert main([*args, "2000"]) == 1
    line = _only_line(capsys.readouterr().err)
    assert "--episodes 2000 of 10 s would hold about 1.5 GiB" in line
    assert not out.exists()


def test_a_huge_episode_count_is_refused_without_listing_its_seeds(tmp_path, capsys):
    """10**7 episodes of 10 s would hold terabytes: refused, and the check itself allocates
    no list of 10**7 seeds (which would take some 400 MB; 10**9 were the kernel's to kill)."""
    import tracemalloc

    from capsule_env.datasets.__main__ import main

    out = tmp_path / "out"
    tracemalloc.start()
    try:
        code = main(["--task", TASK, "--controller", "passive", "--out", str(out),
                     "--episodes", str(10**7)])  # fmt: skip
        peak_b = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert code == 1 and "--episodes 10000000 of 10 s would hold" in _only_line(
        capsys.readouterr().err
    )
    assert peak_b < 50 * 2**20 and not out.exists()


def test_a_dataset_of_another_env_is_one_line(tmp_path, capsys, monkeypatch):
    from minari.data_collector import EpisodeBuffer

    from capsule_env.datasets import bc

    monkeypatch.setattr(bc, "train_bc", _not_reached)
    steps = 5
    buffer = EpisodeBuffer(id=0, seed=0, observations=np.zeros((steps + 1, 4), np.float32),
                           actions=np.zeros(steps, np.int64), rewards=np.ones(steps),
                           terminations=np.zeros(steps, bool),
                           truncations=np.eye(1, steps, steps - 1, dtype=bool)[0],
                           infos={})  # fmt: skip
    with minari_store.datasets_root(tmp_path / "root"), warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        minari.create_dataset_from_buffers(
            "other/cartpole-v0", [buffer], env=gym.spec("CartPole-v1"), algorithm_name="zero"
        )
    assert bc.main(["--dataset-root", str(tmp_path / "root"), *SHORT]) == 1
    assert "was not recorded in a capsule_env env ('CartPole-v1')" in _only_line(
        capsys.readouterr().err
    )


def test_an_out_that_links_to_an_empty_folder_receives_the_dataset(tmp_path, capsys):
    """A datasets folder linked to a larger disk: the dataset lands in the folder linked to,
    read back through the link; a link to nothing is refused before the run."""
    from capsule_env.datasets.__main__ import main

    (tmp_path / "disk").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "disk")
    args = ["--task", TASK, "--controller", "passive", "--episodes", "1", "--episode-length",
            str(LENGTH_S), "--out"]  # fmt: skip
    assert main([*args, str(tmp_path / "link")]) == 0
    assert (tmp_path / "link").is_symlink()
    dataset = load_dataset(tmp_path / "link", f"capsule_env/{TASK}/passive-v0")
    assert dataset.total_steps == 100
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    capsys.readouterr()
    assert main([*args, str(tmp_path / "dangling")]) == 1
    assert "is a symbolic link to nothing" in _only_line(capsys.readouterr().err)
    assert not (tmp_path / "nowhere").exists()


@pytest.mark.rl
def test_a_training_seed_fixes_the_network(tmp_path):
    """The figures' reproducibility: the same seed gives the same weights, another seed others
    (behaviour cloning and TD3+BC, a few steps each)."""
    torch = pytest.importorskip("torch", reason=NO_SB3)
    from capsule_env.datasets import bc
    from capsule_env.datasets.offline_eval import transitions

    _foreign(tmp_path / "root")
    data = transitions(load_dataset(tmp_path / "root", "mine/ride-v0"))
    trainers = [lambda seed: bc.train_bc(data, bc.Args(gradient_steps=20), seed)[0]]
    try:
        import torchrl  # noqa: F401

        from capsule_env.datasets import td3bc

        trainers.append(lambda seed: td3bc.train_td3bc(data, td3bc.Args(gradient_steps=20),
                                                       seed)[0])  # fmt: skip
    except ImportError:  # TorchRL is in the dev extra
        pass
    x = torch.as_tensor(data.observations)
    for train in trainers:
        nets = [train(seed) for seed in (3, 3, 4)]
        with torch.no_grad():
            first, again, other = (net(x) for net in nets)
        assert torch.equal(first, again) and not torch.equal(first, other)
