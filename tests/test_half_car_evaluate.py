"""``evaluate.py --task CapsuleHalfRide-v0`` and the half-car task's card.

evaluate.py runs the half-car's own evaluation (capsule_env.evaluation.half_car) and writes it in
its own JSON layout, the headline ``wk_rms_body_acc_m_s2`` the mean of the floor's three points
(checked here against a rollout of the env written out by hand); the options it cannot honour
are refused with one line; the task card (docs/tasks.md) and the README's table carry the
half-car, its comfort metric stated, its figures the evaluation file's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from capsule_env.evaluation import evaluate
from capsule_env.evaluation.task_cards import CARDED, load_results, readme_table, task_cards
from capsule_env.metrics import wk_weighted_rms
from capsule_env.tasks import DECLARED_TASKS

ROOT = Path(__file__).resolve().parents[1]
TASK = next(t for t in DECLARED_TASKS if t.env_id == "CapsuleHalfRide-v0")


def _passive_floor_wk(seeds: list[int]) -> float:
    """The passive damper's Wk at the floor's three points, mean over points and episodes,
    from the env's own per-step comfort accelerations (evaluation bank: guideway seed 2026)."""
    from capsule_env.envs.declared_vector import DeclaredVectorEnv

    env = DeclaredVectorEnv(len(seeds), guideway_seed=2026, episode_length_s=10.0, damper="passive",
                            **TASK.kwargs)  # fmt: skip
    env.reset(seed=seeds)
    acc = []
    for _ in range(env.batch.max_steps):
        *_, info = env.step(np.zeros((len(seeds), 2), dtype=np.float32))
        acc.append(info["comfort_acceleration_m_s2"])  # (episodes, 3 points)
    per_point = [wk_weighted_rms(np.stack(acc)[:, e, p], env.batch.dt)
                 for e in range(len(seeds)) for p in range(3)]  # fmt: skip
    return float(np.mean(per_point))


@pytest.mark.rl
def test_evaluate_runs_the_half_car_task_in_its_json_layout(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "half.json"
    assert evaluate.main(["--task", "CapsuleHalfRide-v0", "--episodes", "2", "--seed", "1003",
                          "--json", str(out)]) == 0  # fmt: skip
    data = json.loads(out.read_text())
    assert data["seeds"] == [1003, 1004] and data["episodes"] == 2
    assert data["condition"]["task"] == "CapsuleHalfRide-v0"
    rows = data["settings"]["hils"]["controllers"]
    assert {"passive", "lqr-clipped-biexp-meas", "lqr-coupled-biexp-meas",
            "wheelbase-lq-biexp-meas", TASK.shipped_policy} <= set(rows)  # fmt: skip
    for name in ("mpc-coupled-biexp-meas", "wheelbase-mpc-biexp-meas"):  # the half-car MPCs
        solver = rows[name]["solver"]  # their solver's figures over the run
        assert solver["vehicle_steps"] == 2 * 2000 and solver["solves_per_step"] >= 1.0, name
        assert solver["fallback_steps"] >= 0 and rows[name]["gains_tuned"], name
    # a shipped policy's file named as in the package, the same on every machine
    assert data["policies"] == {
        TASK.shipped_policy: f"capsule_env/pretrained/{TASK.shipped_policy}.zip"
    }
    passive = rows["passive"]
    assert passive["wk_rms_body_acc_m_s2"] == pytest.approx(_passive_floor_wk([1003, 1004]),
                                                            rel=1e-9)  # fmt: skip
    for name, row in rows.items():  # the headline: the three points' mean
        points = (row["wk_front_m_s2"], row["wk_centre_m_s2"], row["wk_rear_m_s2"])
        assert row["wk_rms_body_acc_m_s2"] == pytest.approx(np.mean(points), rel=1e-12), name
        assert row["uses_unmeasured_signals"] is (name.endswith("-exact")), name
    assert "| residual-ppo-mpc-half-car |" in capsys.readouterr().out


@pytest.mark.parametrize("extra, named", [
    (["--plots", "PLOTS"], "--plots"), (["--env", "speed_kmh=400"], "--env"),
    (["--controllers", "passive"], "--controllers"), (["--setting", "sim"], "--setting"),
    (["--policy", "x.zip"], "--policy"), (["--episode-length", "5"], "--episode-length"),
    (["--episodes", "1"], "--episodes must be >= 2"), (["--seed", "-1"], "--seed must be in"),
])  # fmt: skip
def test_evaluate_refuses_what_the_half_car_task_does_not_take(extra, named, tmp_path, capsys):
    out = tmp_path / "half.json"
    extra = [str(tmp_path / "plots") if e == "PLOTS" else e for e in extra]
    assert evaluate.main(["--task", "CapsuleHalfRide-v0", *extra, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("evaluate.py: error: ") and named in err
    assert not out.exists() and not (tmp_path / "plots").exists()


def test_the_half_car_is_carded_with_its_metric_and_the_files_figures():
    assert TASK in CARDED
    results = load_results(ROOT / "docs" / "figures")
    page = (ROOT / "docs" / "tasks.md").read_text()
    cards = task_cards(results)
    assert cards in page and readme_table(results) in (ROOT / "README.md").read_text()
    card = cards[cards.index("## `CapsuleHalfRide-v0`") :]
    for words in ("ISO 2631-1 Wk", "front bogie", "centre of mass", "rear bogie", "We-weighted",
                  "`wk_rms_body_acc_m_s2`"):  # fmt: skip
        assert words in card, words
    rows = results[TASK.results]["settings"]["hils"]["controllers"]
    wk = {n: r["wk_rms_body_acc_m_s2"] for n, r in rows.items()}
    score = (wk["passive"] - wk[TASK.shipped_policy]) / (wk["passive"] - wk["oracle"])
    assert (f"| `{TASK.shipped_policy}` | shipped learned policy | measured | "
            f"{wk[TASK.shipped_policy]:.4f} | {score:.3f} |") in card  # fmt: skip
    # the card's best law: the lowest Wk of the laws on measured signals (no policy, no oracle)
    laws = {n: w for n, w in wk.items() if n not in (*data_policies(results), "oracle", "passive")
            and not rows[n]["uses_unmeasured_signals"]}  # fmt: skip
    assert min(laws, key=laws.__getitem__) == TASK.best_classical
    # the advice quotes the file's ratios
    base = wk[TASK.best_classical]
    assert f"{wk['lqr-coupled-biexp-meas'] / base:.3f} x" in TASK.use
    assert f"{wk['wheelbase-lq-biexp-meas'] / base:.3f} x" in TASK.use


def data_policies(results: dict) -> list[str]:
    return list(results[TASK.results].get("policies", {}))


def test_results_name_a_shipped_policy_by_its_path_in_the_package():
    # it gave the absolute path in a checkout (the module lives in agents/, not capsule_env/)
    from capsule_env.agents.learning.policy_files import shown_path
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR

    assert (
        shown_path(PRETRAINED_DIR / "ppo-measured.zip") == "capsule_env/pretrained/ppo-measured.zip"
    )
    assert shown_path("runs/x/best_model.zip") == "runs/x/best_model.zip"
