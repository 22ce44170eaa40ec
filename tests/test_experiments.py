"""experiments/clairvoyant_bound.py: the controller and the oracle side by side, the oracle
never above the controller (its applied currents are one of the starts)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

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


def _run(bound, tmp_path, controller: str, episodes: int, duration: float, max_iter: int):
    """A run without restarts; its JSON."""
    out = tmp_path / "bound.json"
    argv = ["--controller", controller, "--episodes", str(episodes), "--duration",
            str(duration), "--max-iter", str(max_iter), "--restarts", "0", "--json", str(out)]  # fmt: skip
    assert bound.main(argv) == 0
    return json.loads(out.read_text())


def test_short_run_writes_both_and_the_oracle_is_lower(bound, tmp_path):
    data = _run(bound, tmp_path, "skyhook-cont-biexp", 2, 0.6, 4)
    assert len(data["episodes_detail"]) == 2 and data["controller"] == "skyhook-cont-biexp"
    for row, wk_ctrl in zip(data["episodes_detail"], data["wk_controller_m_s2"]):
        assert 0.0 < row["wk_oracle_m_s2"] < wk_ctrl
    assert data["ratio_of_means"] < 1.0


def test_the_oracle_searches_the_controllers_own_episodes(bound, tmp_path):
    # a law whose own options run it on trips (EDS levitation): the oracle searches the same
    # episodes, so the controller's applied currents, one of its starts, replay to the
    # controller's own Wk (the replay equals the env to 1e-12 m/s^2: tests/test_oracle.py);
    # the oracle had searched constant-speed episodes, from the trip's currents
    data = _run(bound, tmp_path, "lqr-sched-biexp-meas", 1, 0.5, 2)
    assert data["env_kwargs"]["speed_profile"] == "trip"
    (row,) = data["episodes_detail"]
    (wk_ctrl,) = data["wk_controller_m_s2"]
    own_start = [v for name, v in row["start_wk_m_s2"].items() if name.startswith("given:")]
    assert own_start == [pytest.approx(wk_ctrl, rel=1e-9)]


def test_bad_controller_is_one_line(bound):
    with pytest.raises(SystemExit, match="unknown 'nope'"):
        bound.main(["--controller", "nope"])
