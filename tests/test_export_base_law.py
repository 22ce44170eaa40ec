"""The contract's ``residual.base_law``: a rig rebuilds a declared vehicle's residual law from it.

The independent facts: the half-car MPC the shipped ``residual-ppo-mpc-half-car`` rides on is
``capsule_env.evaluation.half_car.tuned_mpc("wheelbase-mpc-biexp-meas")`` (what its loader and
the task's rows run); the per-bogie LQR is ``IndependentClippedLQR("half_car")``. A law rebuilt
from the contract's JSON alone (``json.loads``, then its class's public constructor) must give
the same actions as those on a rollout of the half-car task's env. Equal exactly: the same
class with the same arguments (JSON keeps a float's every bit: Python writes the shortest repr
that reads back to the same double), fed the same observations in the same process, computes
the same floating-point operations in the same order (DAQP is deterministic, the solver has no
time limit).
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest

from conftest import NO_SB3, ResidualRig, check_mpc_block, residual_copy

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR  # noqa: E402
from capsule_env.agents.controllers.half_car_mpc import HalfCarMPC  # noqa: E402
from capsule_env.agents.controllers.mpc_solver import solver_available  # noqa: E402
from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, SB3Policy  # noqa: E402

from capsule_env.envs.declared_vector import DeclaredVectorEnv  # noqa: E402
from capsule_env.export import export_policy  # noqa: E402
from capsule_env.export.base_law import rebuild_base_law  # noqa: E402

pytestmark = pytest.mark.rl
NAME, LAW = "residual-ppo-mpc-half-car", "wheelbase-mpc-biexp-meas"
NO_DAQP = "the half-car MPC's QP solver DAQP is not installed (pip install 'capsule-env[mpc]')"


@pytest.fixture(scope="module")
def card(tmp_path_factory) -> dict:
    """The shipped half-car residual's contract, as a rig reads it: JSON text, parsed."""
    files = export_policy(NAME, tmp_path_factory.mktemp("exported"), "c")
    return json.loads(files[f"{NAME}.contract.json"].read_text())


def constructed(block: dict):
    """The law built from the block alone: its class by the path it names, its arguments."""
    module, _, cls_name = block["class"].rpartition(".")
    return getattr(importlib.import_module(module), cls_name)(**block["constructor"])


def drive(laws: list, env_kwargs: dict, steps: int = 300, vehicles: int = 2) -> list[np.ndarray]:
    """Each law's actions (steps, vehicles, slots) on the same observations: a rollout of the
    half-car task's env (``env_kwargs``, guideway bank 3, seeds 40..) driven by the first law;
    each law restarts where an episode does (``episode_start``, NEXT_STEP autoreset)."""
    kwargs = {k: v for k, v in env_kwargs.items() if k != "guideway_seed"}
    env = DeclaredVectorEnv(vehicles, guideway_seed=3, episode_length_s=1.0, **kwargs)
    obs, _ = env.reset(seed=list(range(40, 40 + vehicles)))
    start, ended = np.ones(vehicles, dtype=bool), np.zeros(vehicles, dtype=bool)
    out: list[list[np.ndarray]] = [[] for _ in laws]
    for _ in range(steps):
        for law, rows in zip(laws, out, strict=True):
            rows.append(law.predict(obs, episode_start=start)[0])
        obs, _, terminated, truncated, _ = env.step(out[0][-1].astype(np.float32))
        start, ended = ended, terminated | truncated
    env.close()
    return [np.stack(rows) for rows in out]


def test_the_block_records_every_constructor_argument_and_the_env_it_assumes(card):
    block = check_mpc_block(card, HalfCarMPC)
    assert block["name"] == LAW and block["class"].endswith(".HalfCarMPC")
    assert block["slots"] == ["front_secondary_damper", "rear_secondary_damper"]
    assert block["vehicle_parameters"]["front_bogie_position_m"] == 10.0
    assert block["inverse_model"]["name"] == card["env_kwargs"].get("inverse_model",
                                                                    "bi_exponential")  # fmt: skip


def test_the_contract_alone_rebuilds_the_half_car_mpc(card):
    if not solver_available():
        pytest.skip(NO_DAQP)
    from capsule_env.evaluation.half_car import tuned_mpc

    block = card["residual"]["base_law"]
    reference, rebuilt = tuned_mpc(LAW), constructed(block)
    expected, got = drive([reference, rebuilt], card["env_kwargs"])
    assert expected.shape == (300, 2, 2)
    # not vacuous: the forces spread and the band binds on some steps (the QP acts)
    assert np.std(expected) > 0.02 and rebuilt.counters["solves"] > 600
    np.testing.assert_array_equal(got, expected)
    via_helper = rebuild_base_law(json.loads(json.dumps(block)))
    np.testing.assert_array_equal(drive([reference, via_helper], card["env_kwargs"])[1], expected)


def test_a_changed_weight_in_the_contract_changes_the_actions(card):
    if not solver_available():
        pytest.skip(NO_DAQP)
    from capsule_env.evaluation.half_car import tuned_mpc

    block = json.loads(json.dumps(card["residual"]["base_law"]))
    block["constructor"]["r_force"] *= 4.0
    expected, got = drive([tuned_mpc(LAW), constructed(block)], card["env_kwargs"])
    assert np.max(np.abs(got - expected)) > 0.01


def test_the_rebuilt_law_plus_the_residual_is_the_policy(card):
    """What a rig runs (the rebuilt law, the network's residual, the contract's combination
    rule per slot) is the action the shipped policy gives through its loader."""
    if not solver_available():
        pytest.skip(NO_DAQP)
    from capsule_env.agents.learning.sb3_policy import load_policy

    policy = load_policy(PRETRAINED_DIR / f"{NAME}.zip")
    law = rebuild_base_law(card["residual"]["base_law"])
    network = SB3Policy.load(PRETRAINED_DIR / f"{NAME}.zip")
    scale = card["residual"]["scale"]
    expected, got = drive([policy, ResidualRig(law, network, scale)], card["env_kwargs"], steps=250)
    np.testing.assert_array_equal(got, expected)


def test_rebuilding_refuses_a_contract_built_from_other_parameters(card):
    block = json.loads(json.dumps(card["residual"]["base_law"]))
    block["vehicle_parameters"]["car_body_mass_kg"] += 1.0
    with pytest.raises(ValueError, match=r"base_law\.vehicle_parameters\.car_body_mass_kg"):
        rebuild_base_law(block)
    block = json.loads(json.dumps(card["residual"]["base_law"]))
    block["class"] = "os.system"
    with pytest.raises(ValueError, match="base_law.class must be"):
        rebuild_base_law(block)


def _lqr_residual(folder: Path) -> Path:
    """The half-car residual's files, its metadata's law the per-bogie LQR."""
    return residual_copy(folder, NAME, "lqr-clipped-biexp-meas", "res-lqr")


def test_the_per_bogie_lqr_block_is_its_formula(tmp_path):
    files = export_policy(str(_lqr_residual(tmp_path)), tmp_path / "out", "c")
    card = json.loads(files["res-lqr.contract.json"].read_text())
    block = card["residual"]["base_law"]
    assert block["rig_solves_qp"] is False and block["class"].endswith(".IndependentClippedLQR")
    reference = IndependentClippedLQR("half_car")
    env = DeclaredVectorEnv(2, guideway_seed=3, episode_length_s=1.0, **{
        k: v for k, v in card["env_kwargs"].items() if k != "guideway_seed"})  # fmt: skip
    obs, _ = env.reset(seed=[40, 41])
    rows, expected = [], []
    for _ in range(200):
        rows.append(obs)
        expected.append(reference.predict(obs)[0])
        obs, *_ = env.step(expected[-1].astype(np.float32))
    obs, expected = np.concatenate(rows), np.concatenate(expected)
    assert np.std(expected) > 0.01
    # the formula the block states, from its numbers alone
    columns = np.array([[c["index"] for c in slot] for slot in block["state_columns"]])
    names = [c["name"] for c in card["observation"]["columns"]]
    assert [names[k] for k in columns[0]] == [c["name"] for c in block["state_columns"][0]]
    force = -(obs[:, columns] @ np.array(block["gain_per_slot"]))
    got = np.clip(force / block["constructor"]["max_force_n"], -1.0, 1.0)
    assert expected.dtype == np.float32  # a law's predict rounds its action to float32
    np.testing.assert_allclose(got, expected, rtol=0, atol=6e-8)  # float32's step below 1
    np.testing.assert_array_equal(constructed(block).predict(obs)[0], expected)
