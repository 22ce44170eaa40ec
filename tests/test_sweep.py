"""capsule_env.sweep: study files (checks, seeds), the plain trial functions, the serial runner,
and (``scale``) a 2-trial local Ray Tune sweep: results table, resume, --no-ray equality."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from capsule_env.sweep import KINDS, Kind, Trial, load_study
from capsule_env.sweep.__main__ import main
from capsule_env.sweep.runner import run_trial
from capsule_env.sweep.study import derived_seed

from conftest import NO_RAY

ROOT = Path(__file__).resolve().parent.parent
NO_RL = (
    "stable-baselines3 is not installed (optional, in the rl extra: pip install 'capsule-env[rl]')"
)
# A gain grid small enough for the tests: 2 episodes of 1 s.
GAINS = {"kind": "gains",
         "params": {"controller": "skyhook-cont-biexp", "episodes": 2, "episode_length_s": 1.0},
         "grid": {"gain.c_sky": [3000.0, 30000.0]}}  # fmt: skip
# A tiny PPO run: 2048 steps of 4 vehicles, 128-step rollouts, a 2-episode, 1 s evaluation.
TINY_PPO = {"total_timesteps": 2048, "num_envs": 4, "eval_freq": 0, "eval_episodes": 2,
            "eval_episode_length": 1.0, "checkpoint_freq": 0, "hp.n_steps": 128,
            "hp.batch_size": 256, "hp.n_epochs": 2}  # fmt: skip


def write_study(folder: Path, content: Any, name: str = "study.json") -> Path:
    path = folder / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


def rows(out: Path) -> list[dict[str, Any]]:
    return json.loads((out / "results.json").read_text())["trials"]


def attempts(out: Path, trial: str) -> int:
    return len((out / "trials" / trial / "attempts.log").read_text().splitlines())


# ----------------------------------------------------------------------------- bad study files
BAD = [
    ({"nmae": "x", "trials": [GAINS]}, "unknown key 'nmae'; accepted: name, seed, cpus_per_trial, trials"),
    ({"trials": []}, "trials: expected a non-empty list of blocks"),
    ({"trials": [{**GAINS, "kind": "trian"}]}, "trials[0].kind: unknown kind 'trian'; accepted: train, gains, oracle"),
    ({"trials": [{**GAINS, "replicas": 2}]}, "unknown key 'replicas'; accepted: kind, name, params, grid, replicates, seeds"),
    ({"trials": [{**GAINS, "params": {"controler": "x"}}]}, "unknown parameter 'controler' for kind 'gains'; accepted: controller, setting"),
    ({"trials": [{**GAINS, "params": {"controller": "skyhok"}}]}, "controller: unknown controller 'skyhok'; accepted: passive,"),
    ({"trials": [{**GAINS, "grid": {"gain.c_skyy": [1.0]}}]}, "gain.c_skyy: skyhook-cont-biexp has no such gain; accepted: c_max, c_min, c_sky"),
    ({"trials": [{**GAINS, "grid": {"gain.c_sky": 3000}}]}, "grid.gain.c_sky: expected a non-empty list of values"),
    ({"trials": [{**GAINS, "grid": {"gain.c_sky": ["big"]}}]}, "gain.c_sky: expected a number >= 0, got 'big'"),
    ({"trials": [{**GAINS, "replicates": 3}]}, "trials[0].replicates: kind 'gains' is deterministic"),
    ({"trials": [{**GAINS, "grid": {"env.sped_kmh": [600]}}]}, "unexpected keyword argument 'sped_kmh'; accepted:"),
    ({"trials": [{**GAINS, "params": {**GAINS["params"], "episode_length_s": 0.1}}]}, "episode_length_s 0.1 s (20 control steps) is too short"),
    ({"trials": [{**GAINS, "params": {**GAINS["params"], "episodes": 0}}]}, "episodes: expected an integer >= 1, got 0"),
    ({"seed": -1, "trials": [GAINS]}, "seed: expected an integer >= 0, got -1"),
    ({"trials": [{**GAINS, "name": "g"}, {**GAINS, "name": "g"}]}, "trials[1].name: expected a new label"),
    ({"name": "a b", "trials": [GAINS]}, "name: expected the study's name"),
    ("[1, 2", "not valid JSON"),
]  # fmt: skip


@pytest.mark.parametrize("content, expected", BAD)
def test_bad_study_file_is_one_line_naming_the_key(tmp_path, capsys, content, expected):
    study = write_study(tmp_path, content)
    assert main([str(study), "--out", str(tmp_path / "out"), "--no-ray"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sweep: error: "), err
    assert expected in err, err
    assert not (tmp_path / "out").exists()  # nothing ran, nothing written


# Study files that passed --check and failed only at run time, or ran the wrong thing
# (issue 25): each is refused before anything runs, in one line naming the key.
SKY = {"controller": "skyhook-cont-biexp", "episodes": 1, "episode_length_s": 1.0}
SKY_MEAS = {**SKY, "controller": "skyhook-cont-biexp-meas"}
REFUSED = [
    # a key the controller fixes (its env_kwargs): the trial would run another law by its name
    ({"trials": [{"kind": "gains", "params": {**SKY, "env.action_mode": "current"}}]},
     "env.action_mode: skyhook-cont-biexp fixes action_mode='force'; accepted: env arguments other than those it fixes"),
    ({"trials": [{"kind": "gains", "params": {**SKY_MEAS, "env.observation": "full_state"}}]},
     "env.observation: skyhook-cont-biexp-meas fixes observation='measured'"),
    ({"trials": [{"kind": "gains", "params": SKY, "grid": {"env.max_force_n": [4000.0]}}]},
     "env.max_force_n: skyhook-cont-biexp fixes max_force_n=8000.0 (a gain of skyhook-cont-biexp: give gain.max_force_n)"),
    # keys the trial sets itself
    ({"trials": [{"kind": "gains", "params": {**SKY, "env.episode_length_s": 2.0}}]},
     "env.episode_length_s: the gains trial sets it; give it as the trial's 'episode_length_s'"),
    ({"trials": [{"kind": "gains", "params": {**SKY, "env.setting": "sim"}}]},
     "env.setting: the gains trial sets it; give it as the trial's 'setting'"),
    ({"trials": [{"kind": "oracle", "params": {"env.episode_length_s": 2.0}}]},
     "env.episode_length_s: the oracle trial sets it"),
    # values
    ({"trials": [{"kind": "oracle", "params": {"episode_length_s": 0}}]},
     "episode_length_s must be a positive number of seconds, got 0"),
    ({"trials": [{"kind": "oracle", "params": {"episode_length_s": 0.05}}]},
     "episode_length_s 0.05 s (10 control steps) is too short"),
    ({"trials": [{"kind": "oracle", "params": {"episode_length_s": True}}]},
     "episode_length_s: expected a number, got True"),
    ({"trials": [{"kind": "gains", "params": SKY, "grid": {"gain.c_sky": [3000.0, -3000.0]}}]},
     "gain.c_sky: expected a number >= 0, got -3000.0"),
    ({"trials": [{"kind": "gains", "params": {**SKY, "controller": "preview-lq-biexp", "gain.delay_steps": 1.5}}]},
     "gain.delay_steps: expected an integer >= 0, got 1.5"),
    # seeds beyond what numpy and SB3 take, and replicates without a bound (issue 40)
    ({"trials": [{"kind": "train", "params": {}, "seeds": [2**32]}]},
     "seeds: expected an integer in 0..4294967295, got 4294967296"),
    ({"trials": [{"kind": "train", "params": {}, "seeds": [-1]}]},
     "seeds: expected an integer in 0..4294967295, got -1"),
    ({"trials": [{"kind": "train", "params": {}, "replicates": 1000000}]},
     "replicates: expected an integer in 1..1000, got 1000000"),
    # a key given twice: JSON and YAML keep the last one silently
    ('{"trials": [{"kind": "gains", "params": {"controller": "skyhook-cont-biexp", "episodes": 1, "episodes": 2}}]}',
     "study.json: duplicate key 'episodes': each key may appear once in a mapping"),
]  # fmt: skip


@pytest.mark.parametrize("mode", ["--check", "--no-ray"])
@pytest.mark.parametrize("content, expected", REFUSED)
def test_study_files_that_failed_at_run_time_are_refused(tmp_path, capsys, mode, content, expected):
    study = write_study(tmp_path, content)
    assert main([str(study), "--out", str(tmp_path / "out"), mode]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sweep: error: "), err
    assert expected in err, err
    assert not (tmp_path / "out").exists()  # nothing ran, nothing written


def test_a_yaml_key_given_twice_is_refused_with_its_line(tmp_path, capsys):
    pytest.importorskip("yaml", reason="PyYAML is not installed (in the scale and rl extras)")
    text = ("trials:\n  - kind: gains\n    params:\n      controller: skyhook-cont-biexp\n"
            "      episodes: 1\n      episodes: 2\n")  # fmt: skip
    study = write_study(tmp_path, text, "study.yml")
    for mode in ("--check", "--no-ray"):
        assert main([str(study), "--out", str(tmp_path / "out"), mode]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1, err
        assert "study.yml: duplicate key 'episodes' (line 6): each key may appear once" in err
    # a YAML merge ('<<') that a key then overrides is not a duplicate
    merged = write_study(tmp_path, "trials:\n  - kind: gains\n    params: &p {controller: "
                         "skyhook-cont-biexp, episodes: 1, episode_length_s: 1.0}\n  - kind: gains"
                         "\n    params: {<<: *p, episodes: 2}\n", "merged.yml")  # fmt: skip
    assert main([str(merged), "--check", "--out", str(tmp_path / "out")]) == 0
    assert "'episodes': 2" in capsys.readouterr().out


def test_the_controllers_env_arguments_are_what_a_gains_trial_runs(tmp_path):
    """The accepted env arguments change the env, not the law: a gains trial's rollout is the
    controller on its own env_kwargs plus the env.<key> overrides that are not among them."""
    from capsule_env.agents.controllers.classical import make_controller

    from capsule_env.evaluation.episodes import episode_metrics, run_episodes

    study = load_study(write_study(tmp_path, {"trials": [{"kind": "gains", "params": {
        **SKY, "env.speed_kmh": 600.0}}]}), tmp_path)  # fmt: skip
    ctrl = make_controller("skyhook-cont-biexp")
    env = {**ctrl.env_kwargs, "setting": "hils", "guideway_seed": 0, "speed_kmh": 600.0}
    roll = run_episodes(ctrl, env, episode_length_s=1.0, seeds=[0])
    result = run_trial(study.trials[0])
    assert (
        result["metrics"]["wk_rms_body_acc_m_s2"]
        == episode_metrics(roll, None)["wk_rms_body_acc_m_s2"]
    )


def test_bad_study_files_other_ways(tmp_path, capsys):
    for path, expected in [
        (tmp_path / "missing.json", "cannot read the study file"),
        (write_study(tmp_path, "name: [x", "s.yml"), "not valid YAML"),
        (write_study(tmp_path, "{}", "s.toml"), "a study file ends in .yml, .yaml or .json"),
    ]:
        if path.suffix == ".yml" and importlib.util.find_spec("yaml") is None:
            continue
        assert main([str(path), "--no-ray"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and expected in err, err


def test_bad_study_file_process_exits_2_without_traceback(tmp_path):
    study = write_study(tmp_path, {"trials": [{**GAINS, "kind": "trian"}]})
    proc = subprocess.run([sys.executable, "-m", "capsule_env.sweep", str(study), "--no-ray"],
                          capture_output=True, text=True, cwd=ROOT)  # fmt: skip
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
    assert "unknown kind 'trian'; accepted: train, gains, oracle" in proc.stderr


def test_train_parameters_are_checked(tmp_path, capsys):
    pytest.importorskip("stable_baselines3", reason=NO_RL)
    pytest.importorskip("yaml", reason=NO_RL)
    cases = [
        ({"hp.learning_rte": 0.1}, "hp.learning_rte: not a hyperparameter of ppo"),
        ({"total_timesteps": -5}, "total_timesteps: expected an integer >= 0, got -5"),
        ({"algo": "a2c"}, "algo: unknown algorithm 'a2c'; accepted: ppo, sac, td3"),
        ({"env.guideway_seed": 2026}, "guideway_seed=2026 is a held-out bank"),
        ({"seed": 3}, "unknown parameter 'seed' for kind 'train'; accepted: algo, total_timesteps"),
        ({"eval_episode_length": 0.1}, "eval_episode_length 0.1 s (20 control steps) is too short"),
        # values that failed only at run time, in SB3, naming no key (issue 25)
        ({"hp.n_steps": "abc"}, "hp.n_steps: expected an integer >= 1, got 'abc'"),
        ({"hp.batch_size": 64.0}, "hp.batch_size: expected an integer >= 1, got 64.0"),
        ({"hp.gamma": 1.5}, "hp.gamma: expected a number in [0, 1], got 1.5"),
        ({"hp.learning_rate": "lin_fast"}, "hp.learning_rate: expected a number > 0 or a 'lin_<value>' schedule, got 'lin_fast'"),
        ({"hp.normalize_advantage": 1}, "hp.normalize_advantage: expected true or false, got 1"),
        ({"hp.ent_coef": "x"}, "hp.ent_coef: expected a number, got 'x'"),
        ({"hp.policy_kwargs": "dict(net_arch=big)"}, "hp.policy_kwargs.net_arch: 'big' is not a literal"),
    ]  # fmt: skip
    for params, expected in cases:
        study = write_study(tmp_path, {"trials": [{"kind": "train", "params": params}]})
        for mode in ("--check", "--no-ray"):
            assert main([str(study), mode, "--out", str(tmp_path / "out")]) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and expected in err, err
            assert not (tmp_path / "out").exists()
    # what the hyperparameter file accepts passes: schedules, numbers, null, dict(...) strings
    good = {"hp.learning_rate": "lin_3e-4", "hp.clip_range": 0.1, "hp.clip_range_vf": None,
            "hp.n_steps": 64, "hp.policy_kwargs": "dict(net_arch=[32, 32])", "hp.gamma": 1}  # fmt: skip
    study = write_study(tmp_path, {"trials": [{"kind": "train", "params": good}]})
    assert main([str(study), "--check", "--out", str(tmp_path / "out")]) == 0


@pytest.mark.parametrize("algo", ["sac", "td3", "tqc", "crossq", "recurrentppo"])
def test_train_parameters_of_every_algorithm_are_checked(algo, tmp_path, capsys):
    # the hp values are checked against the algorithm's own constructor: sb3-contrib's TQC,
    # CrossQ and RecurrentPPO included (they once failed with an AttributeError)
    pytest.importorskip("sb3_contrib", reason=NO_RL)
    pytest.importorskip("yaml", reason=NO_RL)
    good = {"algo": algo, "hp.learning_rate": 3e-4, "hp.batch_size": 128}
    study = write_study(tmp_path, {"trials": [{"kind": "train", "params": good}]})
    assert main([str(study), "--check", "--out", str(tmp_path / "out")]) == 0
    capsys.readouterr()
    bad = {**good, "hp.batch_size": 64.0}
    study = write_study(tmp_path, {"trials": [{"kind": "train", "params": bad}]})
    assert main([str(study), "--check", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "hp.batch_size: expected an integer >= 1, got 64.0" in err, err


# ----------------------------------------------------------------------------- seeds
def test_replicates_get_distinct_independent_seeds(tmp_path):
    pytest.importorskip("stable_baselines3", reason=NO_RL)
    pytest.importorskip("yaml", reason=NO_RL)
    block = {"kind": "train", "replicates": 3, "params": TINY_PPO,
             "grid": {"hp.learning_rate": [0.001, 0.0003]}}  # fmt: skip
    study = load_study(write_study(tmp_path, {"seed": 5, "trials": [block]}), tmp_path)
    seeds = [t.seed for t in study.trials]
    assert len(seeds) == 6 and len(set(seeds)) == 6
    assert seeds[:3] == [derived_seed(5, 0, 0, r) for r in range(3)]
    assert seeds[3:] == [derived_seed(5, 0, 1, r) for r in range(3)]
    assert all(0 <= s < 2**31 for s in seeds)
    other = load_study(write_study(tmp_path, {"seed": 6, "trials": [block]}), tmp_path)
    assert not set(seeds) & {t.seed for t in other.trials}  # another root, other streams
    # listed seeds are taken as they are, and may not be shared by two trials
    listed_block = {"kind": "train", "seeds": [0, 1], "params": TINY_PPO}
    listed = load_study(write_study(tmp_path, {"trials": [listed_block]}), tmp_path)
    assert [t.seed for t in listed.trials] == [0, 1]
    shared = write_study(tmp_path, {"trials": [{"kind": "train", "seeds": [0, 1],
                                                "params": TINY_PPO, "grid": block["grid"]}]})  # fmt: skip
    with pytest.raises(ValueError, match=r"trials\[0\]: trials .* would share seed 0"):
        load_study(shared, tmp_path)
    # two blocks (two rows of a results table) may list the same seeds, as train.py --seed S
    # does for every algorithm; a block's own list may not repeat one
    rows = {"trials": [{**listed_block, "name": "a"}, {**listed_block, "name": "b"}]}
    assert [t.seed for t in load_study(write_study(tmp_path, rows), tmp_path).trials] == [
        0,
        1,
        0,
        1,
    ]
    # a derived seed is no other trial's, even one listed in another block
    taken = {"trials": [{"kind": "train", "replicates": 1, "params": TINY_PPO},
                        {"kind": "train", "seeds": [derived_seed(0, 0, 0, 0)],
                         "params": TINY_PPO}]}  # fmt: skip
    with pytest.raises(ValueError, match=f"would share seed {derived_seed(0, 0, 0, 0)}"):
        load_study(write_study(tmp_path, taken), tmp_path)
    repeated = {"trials": [{"kind": "train", "seeds": [3, 3], "params": TINY_PPO}]}
    with pytest.raises(ValueError, match="would share seed 3"):
        load_study(write_study(tmp_path, repeated), tmp_path)


# ----------------------------------------------------------------------------- serial runs
def test_serial_gain_grid_writes_the_table_and_figure(tmp_path, capsys):
    from capsule_env.agents.controllers.classical import PassiveController, make_controller

    from capsule_env.evaluation.episodes import episode_metrics, run_episodes

    out = tmp_path / "out"
    study = write_study(tmp_path, {"name": "gains", "trials": [GAINS]})
    assert main([str(study), "--out", str(out), "--no-ray"]) == 0
    table = rows(out)
    assert [r["trial"] for r in table] == ["gains0-000", "gains0-001"]
    assert [r["param.gain.c_sky"] for r in table] == [3000.0, 30000.0]
    assert all(r["status"] == "finished" and r["attempts"] == 1 for r in table)
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["trial", "block", "kind", "status", "seed"]
    assert {"wk_rms_body_acc_m_s2", "vre_body_mode1_pct", "error"} <= set(header)
    assert (out / "summary.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the row is the plain evaluation: run_episodes + episode_metrics on the training bank
    ctrl = make_controller("skyhook-cont-biexp", c_sky=30000.0)
    env = {"setting": "hils", "guideway_seed": 0}
    roll = run_episodes(ctrl, {**ctrl.env_kwargs, **env}, episode_length_s=1.0, seeds=[0, 1])
    passive = run_episodes(PassiveController(), {**env, **PassiveController.env_kwargs},
                           episode_length_s=1.0, seeds=[0, 1])  # fmt: skip
    m = episode_metrics(roll, passive)
    assert table[1]["wk_rms_body_acc_m_s2"] == m["wk_rms_body_acc_m_s2"]
    assert table[1]["vre_body_mode1_pct"] == m["vre_pct"]["body_mode1"]
    assert table[0]["wk_rms_body_acc_m_s2"] != table[1]["wk_rms_body_acc_m_s2"]
    # a second run does nothing again, and a changed study is refused
    capsys.readouterr()
    assert main([str(study), "--out", str(out), "--no-ray"]) == 0
    assert "finished before, not run again" in capsys.readouterr().out
    assert attempts(out, "gains0-000") == 1
    # a result.json that is not the trial's whole result ('{}', another trial's) is not a
    # finished trial: it runs again (issue 40: '{}' counted as finished)
    for fake in ({}, {"trial": "gains0-001", "metrics": {}, "attempts": 1}):
        (out / "trials" / "gains0-000" / "result.json").write_text(json.dumps(fake))
        assert main([str(study), "--out", str(out), "--no-ray"]) == 0
        stored = json.loads((out / "trials" / "gains0-000" / "result.json").read_text())
        assert stored["trial"] == "gains0-000" and stored["metrics"]
    assert attempts(out, "gains0-000") == 3
    changed = write_study(tmp_path, {"name": "gains", "trials": [{**GAINS, "grid": {
        "gain.c_sky": [1000.0]}}]})  # fmt: skip
    assert main([str(changed), "--out", str(out), "--no-ray"]) == 2
    assert "whose trial 'gains0-000' is changed or gone in study.json" in capsys.readouterr().err
    # a study that only grows (a block appended) continues in the same folder
    grown = write_study(tmp_path, {"name": "gains", "trials": [GAINS, {**GAINS, "grid": {
        "gain.c_sky": [1000.0]}}]}, name="grown.json")  # fmt: skip
    assert main([str(grown), "--out", str(out), "--no-ray"]) == 0
    assert [r["trial"] for r in rows(out)] == ["gains0-000", "gains0-001", "gains1-000"]
    assert attempts(out, "gains0-000") == 3 and attempts(out, "gains1-000") == 1
    first = write_study(tmp_path, {"name": "gains", "trials": [GAINS]}, name="first.json")
    assert main([str(first), "--out", str(out), "--no-ray"]) == 2  # shrinking it: refused


def _flaky(trial: Trial) -> dict[str, float]:
    if Path(trial.params["fail_if"]).exists():
        raise RuntimeError(f"{trial.name} broke")
    return {"wk_rms_body_acc_m_s2": float(trial.params["value"])}


def test_failed_trials_are_reported_and_run_again(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(KINDS, "flaky", Kind("flaky", _flaky, {"fail_if": "", "value": ""}))
    marker = tmp_path / "broken"
    marker.write_text("")
    out = tmp_path / "out"
    study = write_study(tmp_path, {"trials": [
        {"kind": "flaky", "params": {"fail_if": str(tmp_path / "never")}, "grid": {"value": [1]}},
        {"kind": "flaky", "params": {"fail_if": str(marker)}, "grid": {"value": [2]}},
    ]})  # fmt: skip
    assert main([str(study), "--out", str(out), "--no-ray"]) == 1
    err = capsys.readouterr().err
    assert "failed: flaky1-000: RuntimeError: flaky1-000 broke" in err
    result = json.loads((out / "results.json").read_text())
    assert result["failed"] == [{"trial": "flaky1-000", "error": "RuntimeError: flaky1-000 broke"}]
    assert result["counts"] == {"finished": 1, "failed": 1, "not run": 0}
    assert "RuntimeError: flaky1-000 broke" in (out / "trials/flaky1-000/output.log").read_text()
    # --no-retry-failed: nothing runs; then fixed and retried: only the failed trial runs
    assert main([str(study), "--out", str(out), "--no-ray", "--no-retry-failed"]) == 1
    assert (attempts(out, "flaky0-000"), attempts(out, "flaky1-000")) == (1, 1)
    marker.unlink()
    assert main([str(study), "--out", str(out), "--no-ray"]) == 0
    assert (attempts(out, "flaky0-000"), attempts(out, "flaky1-000")) == (1, 2)
    assert [r["wk_rms_body_acc_m_s2"] for r in rows(out)] == [1.0, 2.0]


def test_oracle_kind_runs_the_clairvoyant_bound(tmp_path):
    from capsule_env.oracle import clairvoyant_bound

    study = load_study(write_study(tmp_path, {"trials": [{"kind": "oracle", "params": {
        "episodes": 1, "episode_length_s": 0.5, "max_iter": 3, "env.setting": "sim"}}]}),
        tmp_path)  # fmt: skip
    result = run_trial(study.trials[0])
    direct = clairvoyant_bound({"setting": "sim"}, [1000], 0.5, max_iter=3)
    assert result["metrics"]["wk_rms_body_acc_m_s2"] == float(direct.wk_rms_body_acc_m_s2[0])
    assert result["metrics"]["spread_over_starts_mean_m_s2"] >= 0.0


@pytest.mark.parametrize("kind", ["oracle", "gains"])
def test_a_trial_on_a_short_trip_is_checked_with_its_own_episode_length(kind):
    # a trip of 4.7 s: lift-off 150 -> cruise 300 km/h at 20 m/s^2 (2.08 s), 0.5 s of cruise,
    # braking at 20 m/s^2 (2.08 s); the check had built the env with the default 10 s episode
    # and refused every trial on it
    trip = {"cruise_speed_kmh": 300.0, "lift_off_speed_kmh": 150.0, "acceleration_m_s2": 20.0,
            "braking_m_s2": 20.0, "cruise_duration_s": 0.5}  # fmt: skip
    params = {"env.speed_profile": "trip", "env.trip_params": trip}
    if kind == "gains":
        params["controller"] = "skyhook-cont-biexp-meas"
    KINDS[kind].check({**params, "episode_length_s": 2.0})
    with pytest.raises(ValueError, match="at most the trip's duration 4.6 s .*got 6.0"):
        KINDS[kind].check({**params, "episode_length_s": 6.0})


# ----------------------------------------------------------------------------- Ray Tune
@pytest.mark.scale
@pytest.mark.rl
def test_two_trial_ray_sweep_resume_and_no_ray(local_ray, tmp_path, capsys):
    """Two tiny PPO trials as Ray Tune trials; one starts broken (a corrupt checkpoint in its
    folder) and fails; a restart runs neither the finished trial nor, with
    --no-retry-failed, the failed one; once repaired, only the failed one runs again; the same
    study without Ray gives the same table."""
    pytest.importorskip("stable_baselines3", reason=NO_RL)
    pytest.importorskip("yaml", reason=NO_RL)
    from ray.tune import ExperimentAnalysis

    out = tmp_path / "ray"
    study = write_study(tmp_path, {"name": "two", "trials": [
        {"kind": "train", "name": "ppo", "replicates": 2, "params": TINY_PPO}]})  # fmt: skip
    corrupt = out / "trials/ppo-001/run/checkpoints/ckpt_000000001024.zip"
    corrupt.parent.mkdir(parents=True)
    corrupt.write_text("not a checkpoint")

    def tune_status() -> dict[str, str]:
        trials = ExperimentAnalysis(str(out / "tune")).trials
        return {t.config["trial"]["name"]: t.status for t in trials}

    assert main([str(study), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "failed: ppo-001: RuntimeError: train.py: error: --resume auto: no intact" in err
    table = rows(out)
    assert [r["status"] for r in table] == ["finished", "failed"]
    assert table[0]["num_timesteps"] == 2048 and np.isfinite(table[0]["wk_rms_body_acc_m_s2"])
    assert table[0]["seed"] != table[1]["seed"]
    assert (out / "trials/ppo-000/run/best_model.zip").is_file()
    assert tune_status() == {"ppo-000": "TERMINATED", "ppo-001": "ERROR"}
    for name in ("results.csv", "results.json", "summary.png"):
        assert (out / name).is_file()

    assert main([str(study), "--out", str(out), "--quiet", "--no-retry-failed"]) == 1
    assert (attempts(out, "ppo-000"), attempts(out, "ppo-001")) == (1, 1)

    corrupt.unlink()
    assert main([str(study), "--out", str(out), "--quiet"]) == 0
    assert (attempts(out, "ppo-000"), attempts(out, "ppo-001")) == (1, 2)
    assert tune_status() == {"ppo-000": "TERMINATED", "ppo-001": "TERMINATED"}
    on_ray = rows(out)
    assert [r["status"] for r in on_ray] == ["finished", "finished"]
    assert on_ray[0] == {**table[0]}  # the finished trial's row is the same as before

    serial = tmp_path / "serial"
    assert main([str(study), "--out", str(serial), "--no-ray"]) == 0
    keys = ("trial", "seed", "status", "wk_rms_body_acc_m_s2", "vre_body_mode1_pct",
            "max_stroke_m", "num_timesteps")  # fmt: skip
    assert [{k: r[k] for k in keys} for r in rows(serial)] == [
        {k: r[k] for k in keys} for r in on_ray
    ]


# A driver of the sweep whose kind counts its runs (one file per run) and, while the file
# hold_if exists, holds at its trials from hold_from on: the test interrupts the driver there.
# The kind reaches Ray's workers through worker_process_setup_hook.
COUNTING_DRIVER = """
import os, sys, time
from pathlib import Path
from capsule_env.sweep import Kind, register_kind
from capsule_env.sweep.__main__ import main

def run_counted(trial):
    p = trial.params
    (Path(p["runs"]) / f"{trial.name}.{os.getpid()}.{time.monotonic_ns()}").write_text("")
    if p["value"] >= p["hold_from"] and Path(p["hold_if"]).exists():
        (Path(p["runs"]) / f"holding.{trial.name}").write_text("")
        time.sleep(300)
    return {"wk_rms_body_acc_m_s2": float(p["value"])}

def register():
    register_kind(Kind("counted", run_counted, dict.fromkeys(["runs", "hold_if", "hold_from", "value"], "")))

if __name__ == "__main__":
    register()
    if "--no-ray" not in sys.argv:
        import ray
        ray.init(num_cpus=1, include_dashboard=False,
                 runtime_env={"worker_process_setup_hook": register})
    sys.exit(main(sys.argv[1:]))
"""


def _interrupt_then_continue(tmp_path: Path, signal_to: str, mode: list[str]) -> None:
    """Run a 6-trial counting study, interrupt the driver (``signal_to``: ``"kill -9 driver"``
    or ``"ctrl-c"``, SIGINT to its process group as a terminal sends it) while trial 3 runs,
    then run it again: every trial finishes, and none that had finished runs again."""
    import os
    import signal
    import time

    driver, runs, hold = tmp_path / "driver.py", tmp_path / "runs", tmp_path / "hold"
    driver.write_text(COUNTING_DRIVER)
    runs.mkdir()
    hold.write_text("")
    params = {"runs": str(runs), "hold_if": str(hold), "hold_from": 3}
    study = write_study(tmp_path, {"name": "counted", "trials": [{"kind": "counted",
                        "params": params, "grid": {"value": [0, 1, 2, 3, 4, 5]}}]})  # fmt: skip
    out = tmp_path / "out"
    command = [sys.executable, str(driver), str(study), "--out", str(out), "--quiet", *mode]
    # Tune saves its experiment state at the start, then every 10 s or more: a long period
    # makes "the state was saved before these trials finished" certain, not a matter of timing
    env = {**os.environ, "TUNE_GLOBAL_CHECKPOINT_S": "3600"}
    first = subprocess.Popen(command, cwd=tmp_path, env=env, start_new_session=True,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        while not list(runs.glob("holding.*")):
            assert first.poll() is None and time.monotonic() < deadline, "never reached trial 3"
            time.sleep(0.1)
        finished = sorted(p.parent.name for p in (out / "trials").glob("*/result.json"))
        assert finished == ["counted0-000", "counted0-001", "counted0-002"]
        if signal_to == "ctrl-c":
            os.killpg(first.pid, signal.SIGINT)
        else:
            os.kill(first.pid, signal.SIGKILL)
        try:
            first.wait(timeout=60)
        except subprocess.TimeoutExpired:
            pass
    finally:  # what the driver left (Ray's processes, a held trial)
        try:
            os.killpg(first.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        first.wait()
    hold.unlink()
    again = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr[-2000:]
    counts = {f"counted0-{k:03d}": len(list(runs.glob(f"counted0-{k:03d}.*"))) for k in range(6)}
    assert all(counts[name] == 1 for name in finished), counts  # finished: never again
    assert counts["counted0-003"] == 2  # interrupted while running: ran again
    assert [r["wk_rms_body_acc_m_s2"] for r in rows(out)] == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert [r["status"] for r in rows(out)] == ["finished"] * 6


@pytest.mark.scale
@pytest.mark.parametrize("signal_to", ["kill -9 driver", "ctrl-c"])
def test_finished_trials_never_run_again_on_ray_after_an_interruption(tmp_path, signal_to):
    pytest.importorskip("ray.tune", reason=NO_RAY)
    _interrupt_then_continue(tmp_path, signal_to, [])


def test_finished_trials_never_run_again_without_ray_after_an_interruption(tmp_path):
    _interrupt_then_continue(tmp_path, "ctrl-c", ["--no-ray"])


@pytest.mark.parametrize("path", sorted((ROOT / "experiments" / "studies").glob("*.yml")))
def test_shipped_studies_are_valid(path, tmp_path, capsys):
    pytest.importorskip("stable_baselines3", reason=NO_RL)
    pytest.importorskip("yaml", reason=NO_RL)
    assert main([str(path), "--check", "--out", str(tmp_path / "out")]) == 0
    assert " trials; output " in capsys.readouterr().out
    assert not (tmp_path / "out").exists()


def test_command_line_errors(tmp_path, capsys, monkeypatch):
    study = write_study(tmp_path, {"trials": [GAINS]})
    for argv, expected in [
        ([str(study), "--num-cpus", "0"], "--num-cpus must be >= 1, got 0"),
        (
            [str(study), "--no-ray", "--address", "auto"],
            "--address, --storage and --working-dir need Ray",
        ),
    ]:
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and expected in err, err
    # without Ray installed: a one-line hint at --no-ray
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "ray" else find_spec(name, *a))  # fmt: skip
    assert main([str(study), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "Ray is not installed (pip install 'capsule-env[scale]'); --no-ray runs" in err
