"""The contract's ``residual.base_law`` of a quarter-car residual: a rig rebuilds its law.

The independent facts: the shipped ``residual-ppo-mpc`` (``CapsuleRide-v0``) and
``residual-ppo-mpc-trip`` (``CapsuleTrip-v0``) ride on ``make_controller("mpc-biexp-meas")``,
what their loader (``load_policy``) builds: the registry's factory with the tuned weights it
reads from ``agents/controllers/tuned_gains.json``. A law built from the contract's JSON alone
(``json.loads``, then its class's public constructor; no tuned table read: the rebuilt law's
``gains_tuned`` is False) must give the same actions on a rollout of the task's env. Equal
exactly: the same class with the same arguments (JSON keeps a float's every bit: Python writes
the shortest repr that reads back to the same double) fed the same observations in the same
process computes the same floating-point operations in the same order (DAQP is deterministic;
the solver has no time limit).
"""

from __future__ import annotations

import importlib
import json

import numpy as np
import pytest

from conftest import NO_SB3, ResidualRig, check_mpc_block, residual_copy

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from capsule_env.agents.controllers.classical import FACTORIES, make_controller  # noqa: E402
from capsule_env.agents.controllers.mpc import MPCController  # noqa: E402
from capsule_env.agents.controllers.mpc_solver import solver_available  # noqa: E402
from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, SB3Policy  # noqa: E402

from capsule_env.envs import CapsuleSuspensionVectorEnv  # noqa: E402
from capsule_env.export import export_policy  # noqa: E402
from capsule_env.export.base_law import rebuild_base_law  # noqa: E402
from capsule_env.export.laws_c import c_law_reason, law_class  # noqa: E402
from capsule_env.export.quarter_law import law_arguments  # noqa: E402

pytestmark = pytest.mark.rl
SHIPPED = ("residual-ppo-mpc", "residual-ppo-mpc-trip")
LAW = "mpc-biexp-meas"
NO_DAQP = "the MPC's QP solver DAQP is not installed (pip install 'capsule-env[mpc]')"
#: The registry's feedback laws without a C form (the rig provides them).
NO_C = [n for n in FACTORIES if c_law_reason(n) and getattr(law_class(n), "feedback", True)]


@pytest.fixture(scope="module")
def cards(tmp_path_factory) -> dict[str, dict]:
    """The shipped quarter-car residuals' contracts, as a rig reads them: JSON text, parsed."""
    out = tmp_path_factory.mktemp("exported")
    return {name: json.loads(export_policy(name, out, "c")[f"{name}.contract.json"].read_text())
            for name in SHIPPED}  # fmt: skip


def constructed(block: dict):
    """The law built from the block alone: its class by the path it names, its arguments."""
    module, _, cls_name = block["class"].rpartition(".")
    return getattr(importlib.import_module(module), cls_name)(**block["constructor"])


def drive(laws: list, env_kwargs: dict, steps: int = 300, vehicles: int = 2,
          episode_length_s: float = 1.0) -> tuple[list[np.ndarray], np.ndarray]:  # fmt: skip
    """Each law's actions (steps, vehicles, 1) on the same observations, and the episode-start
    flags: a rollout of the env ``env_kwargs`` (guideway bank 3, seeds 40..) driven by the
    first law; each law restarts where an episode does (``episode_start``, NEXT_STEP)."""
    kwargs = {k: v for k, v in env_kwargs.items() if k != "guideway_seed"}
    env = CapsuleSuspensionVectorEnv(num_envs=vehicles, guideway_seed=3,
                                     episode_length_s=episode_length_s, **kwargs)  # fmt: skip
    obs, _ = env.reset(seed=list(range(40, 40 + vehicles)))
    start, ended = np.ones(vehicles, dtype=bool), np.zeros(vehicles, dtype=bool)
    out: list[list[np.ndarray]] = [[] for _ in laws]
    starts = []
    for _ in range(steps):
        starts.append(start)
        for law, rows in zip(laws, out, strict=True):
            rows.append(law.predict(obs, episode_start=start)[0])
        obs, _, terminated, truncated, _ = env.step(out[0][-1].astype(np.float32))
        start, ended = ended, terminated | truncated
    env.close()
    return [np.stack(rows) for rows in out], np.array(starts)


def test_the_block_records_every_constructor_argument_and_the_env_it_assumes(cards):
    card = cards["residual-ppo-mpc"]
    block = check_mpc_block(card, MPCController)
    assert block["name"] == LAW and block["class"].endswith(".MPCController")
    assert block["in_c_file"] is False
    assert block["constructor"]["observation"] == card["env_kwargs"]["observation"]
    assert block["slots"] == ["secondary_damper"] and block["vehicle"] == "quarter_car"
    assert block["vehicle_parameters"]["car_body_mass_kg"] == 6000.0
    assert block["inverse_model"]["name"] == "bi_exponential"
    names = [c["name"] for c in card["observation"]["columns"]]
    read = block["reads"]["columns"]
    assert [names[c["index"]] for c in read] == [c["name"] for c in read]
    assert {c["name"] for c in read} == {"stroke_m", "stroke_rate_m_s", "levitation_gap_m",
                                         "coil_current_a", "car_body_velocity_estimate_m_s",
                                         "bogie_velocity_estimate_m_s"}  # fmt: skip


@pytest.mark.parametrize("name", SHIPPED)
def test_the_contract_alone_rebuilds_the_mpc(name, cards):
    if not solver_available():
        pytest.skip(NO_DAQP)
    card = cards[name]
    block = card["residual"]["base_law"]
    reference, rebuilt = make_controller(LAW), constructed(block)
    assert rebuilt.gains_tuned is False  # its weights are the contract's, not the table's
    (expected, got), starts = drive([reference, rebuilt], card["env_kwargs"])
    assert expected.shape == (300, 2, 1) and starts[1:].any()  # an episode restarts
    # not vacuous: the forces spread and the QP is solved (more than once on some steps)
    assert np.std(expected) > 0.02 and rebuilt.counters["solves"] > 600
    np.testing.assert_array_equal(got, expected)
    # fresh laws again (a restart forgets all: tests/test_law_restart.py): the same actions
    via_helper = rebuild_base_law(json.loads(json.dumps(block)))
    again = drive([make_controller(LAW), via_helper], card["env_kwargs"])[0]
    np.testing.assert_array_equal(again[1], expected)


def test_a_changed_weight_in_the_contract_changes_the_actions(cards):
    if not solver_available():
        pytest.skip(NO_DAQP)
    card = cards["residual-ppo-mpc"]
    block = json.loads(json.dumps(card["residual"]["base_law"]))
    block["constructor"]["r_force"] *= 4.0
    (expected, got), _ = drive([make_controller(LAW), constructed(block)], card["env_kwargs"])
    assert np.max(np.abs(got - expected)) > 0.01


@pytest.mark.parametrize("name", SHIPPED)
def test_the_rebuilt_law_plus_the_residual_is_the_policy(name, cards):
    """What a rig runs (the rebuilt law, the network's residual, the contract's combination
    rule) is the action the shipped policy gives through its loader."""
    if not solver_available():
        pytest.skip(NO_DAQP)
    from capsule_env.agents.learning.sb3_policy import load_policy

    card = cards[name]
    policy = load_policy(PRETRAINED_DIR / f"{name}.zip")
    law = rebuild_base_law(card["residual"]["base_law"])
    network = SB3Policy.load(PRETRAINED_DIR / f"{name}.zip")
    scale = card["residual"]["scale"]
    rig = ResidualRig(law, network, scale)
    (expected, got), _ = drive([policy, rig], card["env_kwargs"], steps=250)
    assert np.std(expected) > 0.02
    np.testing.assert_array_equal(got, expected)


def test_rebuilding_refuses_a_tampered_contract(cards):
    original = cards["residual-ppo-mpc"]["residual"]["base_law"]
    block = json.loads(json.dumps(original))
    block["vehicle_parameters"]["car_body_mass_kg"] += 1.0
    with pytest.raises(ValueError, match=r"base_law\.vehicle_parameters\.car_body_mass_kg"):
        rebuild_base_law(block)
    block = json.loads(json.dumps(original))
    block["inverse_model"]["parameters"]["upper_a0"] *= 1.01
    with pytest.raises(ValueError, match=r"base_law\.inverse_model\.parameters\.upper_a0"):
        rebuild_base_law(block)
    block = json.loads(json.dumps(original))
    block["class"] = "os.system"
    with pytest.raises(ValueError, match="base_law.class must be"):
        rebuild_base_law(block)
    block = json.loads(json.dumps(original))
    block["constructor"]["horizon_steps"] = 0
    with pytest.raises(ValueError, match="horizon_steps"):
        rebuild_base_law(block)


@pytest.mark.parametrize("name", NO_C)
def test_every_law_without_a_c_form_is_rebuilt_by_its_arguments(name):
    """A residual on any registry law the C file lacks (the MPCs, the preview LQ law, the
    gain-scheduled LQR) gets a constructor that rebuilds it: the same actions as the
    registry's over 100 steps of its env (episodes of 40 steps: restarts at steps 41, 82)."""
    if "mpc" in name.split("-") and not solver_available():
        pytest.skip(NO_DAQP)
    reference = make_controller(name)
    arguments = json.loads(json.dumps(law_arguments(name, reference)))
    rebuilt = type(reference)(**arguments)
    assert rebuilt.gains_tuned is False and rebuilt.gains() == reference.gains()
    kwargs = reference.env_kwargs | {"setting": "hils"}
    (expected, got), starts = drive([reference, rebuilt], kwargs, steps=100,
                                    episode_length_s=0.2)  # fmt: skip
    assert np.flatnonzero(starts[:, 0]).tolist() == [0, 41, 82] and np.std(expected) > 0.005
    np.testing.assert_array_equal(got, expected)


def test_a_law_in_the_c_file_is_named_as_such(tmp_path):
    zip_path = residual_copy(tmp_path, "residual-ppo-mpc", "lqr-clipped-biexp-meas", "res")
    files = export_policy(str(zip_path), tmp_path / "o", "c")
    card = json.loads(files["res.contract.json"].read_text())
    block = card["residual"]["base_law"]
    assert block["name"] == "lqr-clipped-biexp-meas" and block["in_c_file"] is True
    assert block["constructor"] is None and block["rig_solves_qp"] is False
    assert "capsule_law" in block["rebuild"] and "capsule_law" in files["res.c"].read_text()
