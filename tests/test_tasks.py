"""Registered tasks: each is the env with its options, works through every entry point, and its
card's reference scores are the evaluation's."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401  (registers the tasks)
from capsule_env.evaluation.task_cards import load_results, task_cards
from capsule_env.tasks import TASKS, normalised_score, task_named

ROOT = Path(__file__).resolve().parents[1]
RESULTS = json.loads((ROOT / "docs" / "figures" / "evaluation.json").read_text())


def _rollout(env, seed: int, steps: int = 120) -> list[np.ndarray]:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(1)
    out = [obs]
    for _ in range(steps):
        obs, reward, *_ = env.step(
            rng.uniform(-1, 1, size=env.action_space.shape).astype(np.float32)
        )
        out += [obs, np.asarray(reward)]
    return out


@pytest.mark.parametrize("task", TASKS, ids=lambda t: t.env_id)
def test_task_is_the_env_with_its_options(task):
    made = gym.make(task.env_id)
    plain = gym.make("CapsuleSuspension-v0", **task.kwargs)
    assert made.observation_space == plain.observation_space
    for a, b in zip(_rollout(made, 5), _rollout(plain, 5)):
        assert np.array_equal(a, b)
    venv = gym.make_vec(task.env_id, num_envs=3, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=2)
    assert obs.shape == (3, *plain.observation_space.shape)
    venv.close()


def test_shipped_policies_were_trained_on_their_tasks():
    for task in TASKS:
        if not task.shipped_policy:
            continue
        meta = json.loads((ROOT / "capsule_env" / "pretrained" /
                           f"{task.shipped_policy}.json").read_text())  # fmt: skip
        env_kwargs = {k: v for k, v in meta["env_kwargs"].items() if k != "action_mode"}
        assert env_kwargs == json.loads(json.dumps(task.kwargs))  # a tuple is a JSON list
        assert meta["env_kwargs"].get("action_mode", "force") == "force"


def test_reference_laws_read_only_what_the_task_measures():
    results = load_results(ROOT / "docs" / "figures")
    for task in TASKS:
        entry = results[task.results]["settings"][task.setting]["controllers"][task.best_classical]
        assert entry["uses_unmeasured_signals"] is False
        assert entry["preview"] is (task.kwargs.get("preview_points", 0) > 0)


def test_best_classical_is_the_lowest_wk_of_the_laws_reading_the_same_signals():
    # "best tuned classical law" on a card: no other classical row of the task's results file
    # with the same signals (measured, preview or not) has a lower Wk; policies and the oracle
    # are not classical laws.
    results = load_results(ROOT / "docs" / "figures")
    for task in TASKS:
        block = results[task.results]
        rows = block["settings"][task.setting]["controllers"]
        learned = set(block.get("policies", {})) | {"oracle", "passive"}
        best = rows[task.best_classical]
        rivals = {name: m["wk_rms_body_acc_m_s2"] for name, m in rows.items()
                  if name not in learned and m["uses_unmeasured_signals"] is False
                  and m["preview"] is best["preview"]}  # fmt: skip
        assert min(rivals, key=rivals.__getitem__) == task.best_classical, (task.env_id, rivals)
        assert best["preview"] is (task.kwargs.get("preview_points", 0) > 0)


def test_cards_show_the_preview_horizon_each_row_reads():
    # the preview laws read their own 1.0 s (agents/controllers/tuned_gains.json), the task gives 0.5 s
    page = (ROOT / "docs" / "tasks.md").read_text()
    assert (
        "| `preview-mpc-biexp-meas` | best tuned classical law | measured + preview (1 s) |" in page
    )
    assert "| `ppo-preview` | shipped learned policy | measured + preview (0.5 s) |" in page


def test_a_card_without_its_rows_is_named():
    results = load_results(ROOT / "docs" / "figures")
    del results["evaluation.json"]["settings"]["hils"]["controllers"]["mpc-biexp-meas"]
    with pytest.raises(ValueError, match="evaluation.json has no row mpc-biexp-meas for "
                                         "CapsuleRide-v0"):  # fmt: skip
        task_cards(results)


def test_cards_in_sync_and_scores_are_the_evaluations():
    page = (ROOT / "docs" / "tasks.md").read_text()
    assert task_cards(load_results(ROOT / "docs" / "figures")) in page
    hils = RESULTS["settings"]["hils"]["controllers"]
    wk = hils["lqr-clipped-biexp-meas"]["wk_rms_body_acc_m_s2"]
    expected = (0.2596 - 0.2399) / (0.2596 - 0.2116)  # the results page's rounded figures
    score = normalised_score(wk, hils["passive"]["wk_rms_body_acc_m_s2"],
                             hils["oracle"]["wk_rms_body_acc_m_s2"])  # fmt: skip
    assert score == pytest.approx(expected, abs=2e-3)
    assert normalised_score(0.3, 0.3, 0.2) == 0.0 and normalised_score(0.2, 0.3, 0.2) == 1.0


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="task must be one of CapsuleSuspension-v0"):
        task_named("CapsuleRide-v9")
    with pytest.raises(ValueError, match="passive_m_s2 must exceed oracle_m_s2"):
        normalised_score(0.2, 0.2, 0.25)
    assert task_named("CapsuleRide-v0").setting == "hils"


def test_each_card_says_which_law_to_use_with_the_results_figures():
    # the advice quotes figures: they must be the results files' (rounded as quoted)
    results = load_results(ROOT / "docs" / "figures")
    for task in TASKS:
        assert task.use and f"`{task.best_classical}`" in task.use, task.env_id
    hils = {n: r["wk_rms_body_acc_m_s2"] for n, r in RESULTS["settings"]["hils"]["controllers"]
            .items()}  # fmt: skip
    ride, preview = task_named("CapsuleRide-v0").use, task_named("CapsuleRidePreview-v0").use
    assert f"{hils['mpc-biexp-meas'] / hils['lqr-clipped-biexp-meas']:.3f} x" in ride
    assert f"{(hils['lqr-clipped-biexp-meas'] / hils['mpc-biexp-meas'] - 1) * 100:.1f} %" in ride
    lq, mpc = hils["preview-lq-biexp-meas"], hils["preview-mpc-biexp-meas"]
    assert f"{(lq / mpc - 1) * 100:.1f} %" in preview
    trip = results["evaluation-CapsuleTrip-v0.json"]["settings"]["hils"]["controllers"]
    assert f"({trip['lqr-sched-biexp-meas']['wk_rms_body_acc_m_s2']:.4f})" in task_named(
        "CapsuleTrip-v0").use  # fmt: skip


def test_readme_table_of_tasks_in_sync():
    from capsule_env.evaluation.task_cards import readme_table

    readme = (ROOT / "README.md").read_text()
    assert readme_table(load_results(ROOT / "docs" / "figures")) in readme
