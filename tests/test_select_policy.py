"""experiments/select_policy.py: the shipping rule on hand-made figures (choice on the even
profiles, comparison on the odd, ship only when the interval is below 0), the cluster bootstrap
against its definition, a shipped policy compared with itself (difference exactly 0, kept), the
per-episode figures against evaluate's average on the same episodes, and its bad input (one
line, exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import load_script

pytest.importorskip("stable_baselines3")


@pytest.fixture(scope="module")
def sp():
    return load_script("experiments/select_policy.py")


PROFILES = np.array([0, 1, 2, 3, 4, 5, 6, 7])  # even: choice half, odd: comparison half


def test_choice_on_even_profiles_comparison_on_odd(sp):
    # run a is best on the choice half (even profiles) and worst on the comparison half
    a = np.array([0.20, 0.30, 0.20, 0.30, 0.20, 0.30, 0.20, 0.30])
    b = np.array([0.25, 0.21, 0.25, 0.22, 0.25, 0.21, 0.25, 0.22])
    old = np.full(8, 0.26)
    d = sp.decide({"a": a, "b": b}, {"old": old}, PROFILES)
    assert [name for name, _ in d["choice_ranking"]] == ["a", "b"]
    assert d["best"] == "a" and d["best_on_comparison_m_s2"] == pytest.approx(0.30)
    assert d["difference_m_s2"][0] == pytest.approx(0.04) and not d["ship"]
    # a candidate below the shipped policy on every comparison episode ships
    d = sp.decide({"b": b}, {"old": old, "older": old + 0.1}, PROFILES)
    assert d["best_shipped"][0] == "old" and d["ship"]
    assert d["difference_m_s2"][2] < 0.0
    # one that is better on average but not on every profile: interval across 0, kept
    c = np.array([0.2, 0.20, 0.2, 0.27, 0.2, 0.20, 0.2, 0.27])
    assert not sp.decide({"c": c}, {"old": old}, PROFILES)["ship"]
    with pytest.raises(ValueError, match="one shipped"):
        sp.decide({"a": a}, {}, PROFILES)
    with pytest.raises(ValueError, match=">= 2 profiles"):
        sp.decide({"a": a}, {"old": old}, np.array([0, 1, 0, 1, 0, 1, 0, 1]))


def test_cluster_bootstrap_is_the_bootstrap_of_the_clusters(sp):
    rng = np.random.default_rng(0)
    a = rng.normal(0.24, 0.01, 40)
    b = a + 0.002 + rng.normal(0.0, 0.001, 40)
    mean, low, high = sp.paired_interval(a, b, np.arange(40))
    diff = a - b
    assert mean == pytest.approx(diff.mean())
    # one episode per cluster: the bootstrap of a mean, about +-1.96 standard errors
    se = diff.std(ddof=1) / np.sqrt(diff.size)
    assert low == pytest.approx(diff.mean() - 1.96 * se, abs=0.3 * se)
    assert high == pytest.approx(diff.mean() + 1.96 * se, abs=0.3 * se)
    # each cluster twice with the same difference: the same clusters, so the same interval
    twice = sp.paired_interval(np.repeat(a, 2), np.repeat(b, 2), np.repeat(np.arange(40), 2))
    # (our numpy sums in another order: equal to rounding, 1e-9 leaves room for any BLAS/CPU)
    assert twice == pytest.approx((mean, low, high), rel=1e-9)
    with pytest.raises(ValueError, match="one length"):
        sp.paired_interval(np.array([0.2]), np.array([0.3, 0.1]), np.array([0, 1]))


def _run_folder(tmp_path: Path, name: str, shipped: str) -> Path:
    """A train.py-like folder holding a copy of a shipped policy as its best_model."""
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR
    from capsule_env.agents.learning.ship import ship_policy

    run = tmp_path / name
    run.mkdir()
    ship_policy(PRETRAINED_DIR / f"{shipped}.zip", "best_model", folder=run)
    return run


def test_the_default_shipped_policy_is_the_tasks(sp, tmp_path):
    _run_folder(tmp_path, "run-a", "ppo-measured")
    args = sp._parser().parse_args(["--runs", str(tmp_path / "run-*"), "--json",
                                    str(tmp_path / "s.json")])  # fmt: skip
    # CapsuleRide-v0's card names residual-ppo-mpc since 2026-11-26 (not ppo-measured)
    assert list(sp.load_inputs(args)["shipped"]) == ["residual-ppo-mpc"]


def test_a_shipped_policy_against_itself_is_kept(sp, tmp_path, capsys):
    run = _run_folder(tmp_path, "run-a", "ppo-measured")
    out = tmp_path / "sel.json"
    argv = ["--runs", str(tmp_path / "run-*"), "--episodes", "10", "--json", str(out),
            "--law", "passive", "--shipped", "ppo-measured"]  # fmt: skip
    assert sp.main(argv) == 0
    result = json.loads(out.read_text())
    d = result["decision"]
    assert d["best_shipped"][0] == "ppo-measured"  # the one named, not the task's default
    assert d["difference_m_s2"] == [0.0, 0.0, 0.0] and not d["ship"]
    assert "keep ppo-measured" in capsys.readouterr().out
    assert result["seeds"] == list(range(10)) and result["guideway_seed"] == 11
    # per episode, then averaged = evaluate's average over the same episodes of the bank
    from capsule_env.agents.learning.sb3_policy import load_policy

    from capsule_env.evaluation.episodes import episode_metrics, run_episodes
    from capsule_env.tasks import task_named

    kwargs = {**task_named("CapsuleRide-v0").kwargs, "guideway_seed": 11, "guideway_bank_size": 128}
    rollout = run_episodes(load_policy(run / "best_model.zip"), kwargs, seeds=list(range(10)))
    whole = episode_metrics(rollout, None)["wk_rms_body_acc_m_s2"]
    per_episode = result["per_episode_wk_m_s2"]["runs"][str(run)]
    # one episode at a time vs all at once: the same filters, summed in another order (rel 1e-9:
    # rounding of the averaging, whatever the CPU)
    assert np.mean(per_episode) == pytest.approx(whole, rel=1e-9)
    assert np.ptp(per_episode) > 0.0
    assert result["per_episode_wk_m_s2"]["shipped"]["ppo-measured"] == per_episode
    # the reference law: the same episodes, not a candidate, worse than the policy
    assert [name for name, _ in d["choice_ranking"]] == [str(run)]
    assert result["laws_wk_m_s2"]["passive"] > np.mean(per_episode)
    assert result["files"][str(run / "best_model.zip")]["sha256"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--task", "Nope-v0"], "--task must be one of"),
        (["--episodes", "9"], "--episodes must be in [10, 1000]"),
        (["--episodes", "3.5"], "--episodes: not an integer"),
        (["--first-seed", str(2**70)], "--first-seed must be in [0, 2**62]"),
        (["--shipped", "../pretrained/ppo-measured"], "--shipped must be one of"),
        (["--law", "no-such-law"], "'no-such-law' is not a classical controller"),
        (["--law", "preview-lq-biexp-meas"], "was not made for CapsuleRide-v0"),
        (["--task", "CapsuleTrip-v0"], "was not made for CapsuleTrip-v0"),
        (["--bogus"], "unrecognized arguments"),
    ],
)
def test_bad_input_is_one_line(sp, tmp_path, capsys, extra, message):
    _run_folder(tmp_path, "run-a", "ppo-measured")
    argv = ["--runs", str(tmp_path / "run-a"), "--json", str(tmp_path / "x.json"), *extra]
    try:
        code = sp.main(argv)
    except SystemExit as done:  # argparse's own errors (one line: capsule_env.common.cli)
        code = done.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "x.json").exists()


def test_a_corrupt_policy_or_a_bad_json_path_is_one_line(sp, tmp_path, capsys):
    run = _run_folder(tmp_path, "run-a", "ppo-measured")
    good = ["--runs", str(run), "--episodes", "10"]
    assert sp.main([*good, "--json", str(tmp_path)]) == 2  # a folder
    assert "--json must be a file" in capsys.readouterr().err
    assert sp.main([*good, "--json", str(tmp_path / "no" / "x.json")]) == 2
    assert "--json must be a file" in capsys.readouterr().err
    (run / "best_model.zip").write_bytes(b"not a zip")
    assert sp.main([*good, "--json", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err
    assert "does not load" in err and err.count("\n") == 1
    assert sp.main(["--runs", str(tmp_path / "none*"), "--json", str(tmp_path / "x.json")]) == 2
    assert "matches no train.py output folder" in capsys.readouterr().err


def test_a_run_reading_another_preview_horizon_is_refused(sp, tmp_path, capsys):
    """A policy for the preview task must read its 0.5 s preview (ppo-preview does); the
    same 32 points over another horizon are other signals."""
    import argparse

    from capsule_env.tasks import task_named

    task = dict(task_named("CapsuleRidePreview-v0").kwargs)
    own = {"observation": "measured", "preview_points": 32}
    assert sp._reads_the_task({**own, "preview_horizon_s": 0.5}, task, "hils", trained=True)
    assert not sp._reads_the_task({**own, "preview_horizon_s": 1.0}, task, "hils", trained=True)
    assert not sp._reads_the_task({"observation": "measured"}, task, "hils", trained=True)
    _run_folder(tmp_path, "run-a", "ppo-preview")
    args = argparse.Namespace(task="CapsuleRidePreview-v0", episodes=10, profiles=128,
                              first_seed=0, json=tmp_path / "x.json", shipped=[],
                              law=["preview-lq-biexp-meas"], runs=[str(tmp_path / "run-a")])  # fmt: skip
    with pytest.raises(ValueError, match="preview-lq-biexp-meas .laws. was not made for"):
        sp.load_inputs(args)  # the law reads 1.0 s
    args.law = []
    inputs = sp.load_inputs(args)
    assert list(inputs["shipped"]) == ["ppo-preview"] and len(inputs["runs"]) == 1
