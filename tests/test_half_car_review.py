"""A review of the half-car task: the PPO script's schedule and checkpoints, the CLIs' bad
input, and the half-car page's tables against the evaluation files they quote."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PPO_SCRIPT = ROOT / "experiments" / "half_car_ppo.py"


def _ppo_script():
    spec = importlib.util.spec_from_file_location("half_car_ppo_under_test", PPO_SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up
    spec.loader.exec_module(module)
    return module


def _record_learning_rates(monkeypatch) -> list[tuple[int, float]]:
    """(steps done, learning rate) at each PPO update."""
    from stable_baselines3 import PPO

    seen: list[tuple[int, float]] = []
    train = PPO.train

    def recording(self):
        train(self)  # sets the optimiser's rate from the schedule first
        seen.append((self.num_timesteps, self.policy.optimizer.param_groups[0]["lr"]))

    monkeypatch.setattr(PPO, "train", recording)
    return seen


def test_the_learning_rate_decays_linearly_over_the_run_across_checkpoints(tmp_path, monkeypatch):
    """``lin_1e-3``: 1e-3 (1 - steps / total) at every update, whatever the checkpoints, also
    across a resume; never negative (2 vehicles x 64 steps: an update every 128 steps, so
    the first chunk of 300 ends at 384)."""
    pytest.importorskip("stable_baselines3")
    script = _ppo_script()
    seen = _record_learning_rates(monkeypatch)
    args = script.Args(tmp_path / "run", seeds=(0,), total_timesteps=640, num_envs=2,
                       checkpoint_every=300)  # fmt: skip
    save = script._save_atomic

    class Interrupted(Exception):
        pass

    def interrupt_after_the_first_checkpoint(model, env, folder, stem):
        save(model, env, folder, stem)
        raise Interrupted

    monkeypatch.setattr(script, "_save_atomic", interrupt_after_the_first_checkpoint)
    with pytest.raises(Interrupted):
        script.train_seed(args, 0)
    monkeypatch.setattr(script, "_save_atomic", save)
    script.train_seed(args, 0)  # resumes from step_384
    steps = np.array([s for s, _ in seen])
    rates = np.array([r for _, r in seen])
    np.testing.assert_array_equal(steps, [128, 256, 384, 512, 640])
    np.testing.assert_allclose(rates, 1e-3 * (1.0 - steps / 640), rtol=1e-9, atol=1e-15)


def test_a_checkpoint_is_never_a_model_without_its_normaliser(tmp_path):
    """A save that fails on the normaliser leaves no ``step_*.zip`` (resume would pick it and
    fail to load its normaliser) and no temporary file."""
    script = _ppo_script()

    class Model:
        def save(self, path):
            Path(path).write_bytes(b"model")

    class FailingNormaliser:
        def save(self, path):
            Path(path).write_bytes(b"half")
            raise OSError("disk full")

    with pytest.raises(OSError):
        script._save_atomic(Model(), FailingNormaliser(), tmp_path, "step_100")
    assert script._newest_checkpoint(tmp_path) is None
    assert list(tmp_path.iterdir()) == []


def test_the_clis_refuse_a_missing_output_folder_before_running(tmp_path, monkeypatch, capsys):
    """One line on stderr, exit 2, nothing run or created (not a traceback after the run)."""
    from capsule_env.evaluation import half_car

    def must_not_run(*args, **kwargs):
        raise AssertionError("ran before checking --out")

    monkeypatch.setattr(half_car, "evaluate", must_not_run)
    missing = tmp_path / "missing"
    assert half_car.main(["--out", str(missing / "x.json"), "--episodes", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--out" in err and "Traceback" not in err

    script = _ppo_script()
    monkeypatch.setattr(script, "evaluate", must_not_run)
    with pytest.raises(SystemExit) as stop:
        script.main(["--out", str(missing), "--evaluate"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--out" in err
    assert not missing.exists()


def _table(text: str, header: str) -> list[list[str]]:
    """The body cells of the Markdown table whose header row starts with ``header``."""
    rows = []
    for line in text[text.index(header) :].splitlines()[2:]:
        if not line.startswith("|"):
            break
        rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows


def _agrees(quoted: str, value: float) -> bool:
    """``quoted`` is ``value`` rounded to the digits quoted."""
    digits = len(quoted.split(".")[1]) if "." in quoted else 0
    return abs(round(value, digits) - float(quoted)) < 0.5 * 10.0**-digits


def test_the_pages_results_table_quotes_the_evaluation_file():
    """Every number of the half-car page's results table is the JSON's, rounded as quoted."""
    text = (ROOT / "docs" / "half-car.md").read_text()
    data = json.loads(
        (ROOT / "docs" / "figures" / "evaluation-CapsuleHalfRide-v0.json").read_text()
    )
    rows = data["settings"]["hils"]["controllers"]
    table = _table(text, "| row | Wk mean")
    names = [re.search(r"`([^`]+)`", r[0]).group(1) if "`" in r[0] else r[0] for r in table]
    assert set(names) == set(rows)
    wrong = []
    for name, cells in zip(names, table, strict=True):
        r = rows[name]
        quoted = re.findall(r"[0-9]+\.[0-9]+|(?<![.\d])1(?![.\d])", " ".join(cells[1:]))
        values = [r["wk_rms_body_acc_m_s2"], *r["wk_rms_body_acc_m_s2_ci95"],
                  r["ratio_to_independent_lqr"]]  # fmt: skip
        if name != "lqr-clipped-biexp-meas":
            values += r["ratio_to_independent_lqr_ci95"]
        values += [r["wk_front_m_s2"], r["wk_centre_m_s2"], r["wk_rear_m_s2"],
                   r["we_rms_pitch_rad_s2"]]  # fmt: skip
        assert len(quoted) == len(values), (name, quoted)
        wrong += [(name, q, v) for q, v in zip(quoted, values, strict=True) if not _agrees(q, v)]
    assert wrong == []


def test_the_pages_learned_table_quotes_the_learned_file():
    """Each seed's Wk (its mean over the episodes) and the IQM ratio with its interval."""
    text = (ROOT / "docs" / "half-car.md").read_text()
    data = json.loads((ROOT / "docs" / "figures" / "learned-CapsuleHalfRide-v0.json").read_text())
    table = _table(text, "| group | each seed's Wk")
    groups = ("ppo", "residual-ppo", "residual-ppo-mpc", "residual-ppo-mpc-lr1e-4")
    assert len(table) == len(groups)
    for cells, group in zip(table, groups, strict=True):
        seeds = [float(np.mean(v)) for v in data[f"{group}_per_seed"].values()]
        quoted = re.findall(r"[0-9]+\.[0-9]+", cells[1])
        assert len(quoted) == len(seeds) and all(map(_agrees, quoted, seeds))
        for cell, law in ((cells[2], "lqr"), (cells[3], "mpc")):
            ratio = re.findall(r"[0-9]+\.[0-9]+", cell)
            assert len(ratio) == 3 and all(map(_agrees, ratio, data[f"{group}_iqm_ratio_to_{law}"]))
