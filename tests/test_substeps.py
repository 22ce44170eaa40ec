"""The automatic substep rule against a much finer step, vehicle by vehicle.

The promise (``capsule_env.plant.substeps.substep_tables``): the damper force stays within 0.5 % RMS
of a run with 10 times as many substeps (at least 100 per control step) for *every* vehicle,
for every plant damper, both settings and randomised vehicles. Each vehicle's substeps come
from its own parameters, so a light, stiff randomised vehicle gets more than the nominal one.
The fine run is the same env with a fixed ``substeps``: the same vehicles, guideway windows and
current commands (random, changing every step: the hardest case for the damper's transients).
"""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import PLANT_DAMPERS, EnvConfig
from capsule_env.plant.substeps import MAX_AUTO_SUBSTEPS, substep_tables

TOLERANCE = 0.005


def _forces(config: EnvConfig, actions: np.ndarray) -> tuple[np.ndarray, CapsuleBatch]:
    batch = CapsuleBatch(config, actions.shape[1])
    batch.seed(3)
    batch.reset()
    force = np.empty_like(actions)
    for t, a in enumerate(actions):
        batch.step(a)
        force[t] = batch.signals[8]
    return force, batch


def _relative_errors(kwargs: dict, vehicles: int = 48, seconds: float = 2.0) -> np.ndarray:
    """Per vehicle: RMS(F_auto - F_fine) / RMS(F_fine), random current commands (NaN or inf
    where either run is not finite: the callers' ``err.max() < TOLERANCE`` then fails)."""
    rate = kwargs.get("control_rate_hz", 200.0)
    steps = int(round(seconds * rate))
    actions = np.random.default_rng(5).uniform(-1.0, 1.0, (steps, vehicles))
    kwargs = {"action_mode": "current", "episode_length_s": seconds, **kwargs}
    auto, batch = _forces(EnvConfig(**kwargs), actions)
    fine_substeps = max(100, 10 * int(batch.sub_table.max()))
    fine, _ = _forces(EnvConfig(**kwargs, substeps=fine_substeps), actions)
    scale = np.sqrt(np.mean(fine**2, axis=0))
    assert np.all(scale > 50.0)  # the guideway and the commands really work the damper
    return np.sqrt(np.mean((auto - fine) ** 2, axis=0)) / scale


@pytest.mark.parametrize("randomization", [0.0, 0.9])
@pytest.mark.parametrize("setting", ["sim", "hils"])
@pytest.mark.parametrize("damper", PLANT_DAMPERS)
def test_force_within_half_percent_of_a_much_finer_step(damper, setting, randomization):
    err = _relative_errors(
        {"damper": damper, "setting": setting, "vehicle_randomization": randomization}
    )
    assert err.max() < TOLERANCE, f"worst vehicle {err.argmax()}: {100 * err.max():.3f} %"


@pytest.mark.slow
@pytest.mark.parametrize("control_rate_hz", [50.0, 1000.0])
@pytest.mark.parametrize("damper", ["reference", "bi_exponential", "bouc_wen"])
def test_force_accuracy_at_other_control_rates(damper, control_rate_hz):
    for setting in ("sim", "hils"):
        kwargs = {"damper": damper, "setting": setting, "control_rate_hz": control_rate_hz,
                  "vehicle_randomization": 0.9}  # fmt: skip
        err = _relative_errors(kwargs, vehicles=32)
        assert err.max() < TOLERANCE, f"{setting}: {100 * err.max():.3f} %"


@pytest.mark.slow
def test_force_accuracy_with_random_speeds():
    kwargs = {"setting": "hils", "speed_range_kmh": (100.0, 1200.0), "vehicle_randomization": 0.5}
    assert _relative_errors(kwargs).max() < TOLERANCE


def test_force_mode_commands_replayed_with_a_much_finer_step():
    # In force mode the commands depend on the (noisy, delayed) measurements, so two runs
    # with different substeps take different paths: replay the currents the force-mode run
    # applied, open loop, with a 10x finer step, and compare the damper force.
    n, steps = 32, 400
    kwargs = {"setting": "hils", "vehicle_randomization": 0.9, "episode_length_s": 2.0}
    batch = CapsuleBatch(EnvConfig(**kwargs), n)
    batch.seed(7)
    batch.reset()
    actions = np.random.default_rng(1).uniform(-1.0, 1.0, (steps, n))
    applied = np.empty_like(actions)
    force = np.empty_like(actions)
    for t in range(steps):
        batch.step(actions[t])
        applied[t] = batch.applied_current
        force[t] = batch.signals[8]
    fine_kwargs = {**kwargs, "action_mode": "current", "control_delay_steps": 0}
    fine_kwargs["substeps"] = 10 * int(batch.sub_table.max())
    replay_actions = 2.0 * applied / batch.i_max - 1.0
    fine = np.empty_like(actions)
    fine_batch = CapsuleBatch(EnvConfig(**fine_kwargs), n)
    fine_batch.seed(7)
    fine_batch.reset()
    for t in range(steps):
        fine_batch.step(replay_actions[t])
        fine[t] = fine_batch.signals[8]
    np.testing.assert_array_equal(fine_batch.vehicle_params, batch.vehicle_params)
    err = np.sqrt(np.mean((force - fine) ** 2, axis=0)) / np.sqrt(np.mean(fine**2, axis=0))
    assert err.max() < TOLERANCE


def test_each_vehicle_gets_the_table_of_its_own_parameters():
    config = EnvConfig(setting="hils", vehicle_randomization=0.9)
    batch = CapsuleBatch(config, 16)
    batch.seed(0)
    batch.reset()
    rates = config.input_rate_rad_s(batch.speed)
    expected = substep_tables(config.plant_damper, config.dt_s, batch.vehicle_params, rates)
    np.testing.assert_array_equal(batch.sub_table, expected)
    assert len({tuple(row) for row in batch.sub_table}) > 1  # they really differ
    # A light bogie on a stiff levitation has a 4.4x faster bogie mode: more substeps at 0 A.
    nominal = substep_tables(config.plant_damper, config.dt_s, config.packed_vehicle)
    light = config.packed_vehicle * [1.0, 0.1, 1.0, 1.9, 1.0]
    assert substep_tables(config.plant_damper, config.dt_s, light)[0, 0] > nominal[0, 0]


def test_too_stiff_a_configuration_is_refused_not_run_with_a_million_substeps():
    with pytest.raises(ValueError, match="substeps per control step"):
        EnvConfig(damper_params={"c1a": 1e12, "alpha_a": 1e12}, setting="hils")
    with pytest.raises(ValueError, match="bogie_mass_kg"):
        EnvConfig(vehicle_params={"bogie_mass_kg": 1e-9})
    # an explicit substeps is the user's choice; the cap only limits the automatic rule
    assert EnvConfig(substeps=2000).substeps == 2000
    assert MAX_AUTO_SUBSTEPS >= 100


@pytest.mark.parametrize("damper", ["reference", "bouc_wen"])
def test_force_accuracy_across_the_operating_envelope(damper):
    """On trips with EDS levitation, spans and payload (CapsuleTrip-v0's physics), every
    vehicle's force within the bound at every speed of its window: the tables are computed at
    the trip's highest speed and the levitation's stiffness limit."""
    kwargs = {"damper": damper, "setting": "hils", "levitation": "eds", "speed_profile": "trip",
              "spans": "continuous", "payload_range": (-0.3, 0.4), "vehicle_randomization": 0.3}  # fmt: skip
    err = _relative_errors(kwargs, vehicles=24)
    assert err.max() < TOLERANCE, f"worst vehicle {err.argmax()}: {100 * err.max():.3f} %"


@pytest.mark.parametrize("shape", ["continuous", "simply_supported"])
def test_force_accuracy_on_short_spans(shape):
    """Spans shorter than the random irregularity's shortest wavelength: the substeps follow
    their harmonics (``config.input_rate_rad_s``)."""
    kwargs = {"setting": "sim", "spans": shape, "span_params": {"span_m": 1.0, "sag_m": 0.01}}
    assert _relative_errors(kwargs, vehicles=8).max() < TOLERANCE


@pytest.mark.parametrize("c_p", [-2e4, 2e4])
@pytest.mark.parametrize("setting", ["sim", "hils"])
def test_force_accuracy_at_the_ends_of_the_levitation_damping_range(setting, c_p):
    kwargs = {"setting": setting, "vehicle_params": {"levitation_damping_n_s_per_m": c_p}}
    assert _relative_errors(kwargs, vehicles=8).max() < TOLERANCE
