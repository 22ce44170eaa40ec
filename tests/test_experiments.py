"""experiments/clairvoyant_bound.py: its open-loop replay is the env's plant, its batched
gradient perturbs the right steps, and a short search improves on Skyhook."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bound():
    spec = importlib.util.spec_from_file_location(
        "clairvoyant_bound", ROOT / "experiments" / "clairvoyant_bound.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_short_search_replays_the_env_exactly_and_beats_skyhook(bound, tmp_path):
    out = tmp_path / "bound.json"
    argv = ["--episodes", "2", "--duration", "0.6", "--max-iter", "4", "--json", str(out)]
    assert bound.main(argv) == 0
    data = json.loads(out.read_text())
    assert len(data["episodes_detail"]) == 2  # one row per episode asked for
    for row in data["episodes_detail"]:
        # Skyhook's commands, delayed by the env's control delay and replayed open loop
        # through step_batch, give the env's recorded body acceleration bit for bit.
        assert row["replay_error_rel"] == 0.0
        # the search starts from Skyhook's own sequence: a few iterations already improve it
        assert 0.0 < row["wk_clairvoyant_m_s2"] < row["wk_skyhook_m_s2"]
        assert row["max_stroke_m"] < 0.05
    assert data["ratio_of_means"] < 1.0


def test_batched_gradient_matches_separate_central_differences(bound):
    from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv
    from capsule_env.evaluation import EVALUATION_GUIDEWAY_SEED

    env = CapsuleSuspensionVectorEnv(
        num_envs=1, setting="hils", episode_length_s=0.5, guideway_seed=EVALUATION_GUIDEWAY_SEED
    )
    env.reset(seed=1000)
    ep = bound.Episode(env.batch, 0, env.batch.max_steps)
    u = np.random.default_rng(0).uniform(0.2, 1.3, ep.n_steps)
    _, grad = ep.objective(u, delta=1e-4)
    for j in (5, 40, 77):
        plus, minus = u.copy(), u.copy()
        plus[j] += 1e-4
        minus[j] -= 1e-4
        wk = ep.wk(np.stack([plus, minus]), substeps=bound.FIXED_SUBSTEPS)
        central = (wk[0] - wk[1]) / 2e-4
        assert abs(central) > 0.0
        assert grad[j] == pytest.approx(central, rel=0.05, abs=1e-6)
