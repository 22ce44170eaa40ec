"""Tests of capsule_env.sensitivity.csdc_variants against independent facts.

Facts used: the env's compiled force-mode CSDC (the same law on the same measurements, in
another code path) for the exact observer with the continuous law; the exact closed-form
hysteresis update, to which a forward-Euler observer must converge at first order as its step
shrinks; the two-level law's definition (only 0 A or i_max).
"""

from __future__ import annotations

import numpy as np
import pytest
from capsule_env.agents.controllers.classical import make_controller

from capsule_env.dampers import BoucWenDamper
from capsule_env.dampers.hysteresis import hysteresis_update
from capsule_env.evaluation.episodes import episode_metrics, run_episodes
from capsule_env.identification.constrained import SPENCER_SHAPE
from capsule_env.sensitivity.csdc_variants import CSDCVariant, InverseSkyhook, euler_z_step

SEEDS = [1000, 1001]
LENGTH_S = 2.0


def _variant(observer: str, law: str, substeps: int = 1) -> InverseSkyhook:
    return InverseSkyhook(lambda n: CSDCVariant(BoucWenDamper(), n, observer, law, 0.005, substeps))


@pytest.fixture(scope="module")
def passive():
    p = make_controller("passive")
    return run_episodes(p, {**p.env_kwargs, "setting": "sim"}, seeds=SEEDS,
                        episode_length_s=LENGTH_S)  # fmt: skip


def test_exact_continuous_variant_is_the_envs_csdc(passive):
    env_csdc = make_controller("skyhook-csdc")
    ref = run_episodes(env_csdc, {**env_csdc.env_kwargs, "setting": "sim"}, seeds=SEEDS,
                       episode_length_s=LENGTH_S)  # fmt: skip
    pol = _variant("exact", "continuous")
    got = run_episodes(pol, {**pol.env_kwargs, "setting": "sim"}, seeds=SEEDS,
                       episode_length_s=LENGTH_S)  # fmt: skip
    # the current-mode action passes through float32 (the action space): 1.5 A * 2^-23 ~ 2e-7 A
    # per step, and the trajectories drift apart by about that
    diff = np.abs(got.signals["current_command_a"] - ref.signals["current_command_a"])
    assert np.median(diff) < 1e-5
    a, b = episode_metrics(got, passive)["vre_pct"], episode_metrics(ref, passive)["vre_pct"]
    for key in a:
        assert a[key] == pytest.approx(b[key], abs=0.05), key


def test_euler_observer_converges_to_the_exact_update_at_first_order():
    damper = BoucWenDamper(**SPENCER_SHAPE)  # z_max = sqrt(A / (gamma + beta)) = 6.4 mm
    t = np.linspace(0.0, 1.0, 201)  # 200 control steps of 5 ms over one period
    x = 0.02 * np.sin(2.0 * np.pi * t)
    exact = 0.0
    errors = {n: 0.0 for n in (100, 1000, 10000)}
    z = {n: np.zeros(1) for n in errors}
    for k in range(1, t.size):
        exact = hysteresis_update(exact, x[k] - x[k - 1], damper.a_coef, damper.gamma, damper.beta)
        v_mid = np.array([(x[k] - x[k - 1]) / (t[k] - t[k - 1])])  # the step's mean rate
        for n in errors:
            z[n] = euler_z_step(z[n], v_mid, t[k] - t[k - 1], damper, n)
            errors[n] = max(errors[n], abs(float(z[n][0]) - exact))
    z_max = np.sqrt(damper.a_coef / (damper.gamma + damper.beta))
    assert errors[100] > errors[1000] > errors[10000]
    assert errors[10000] < 1e-2 * z_max
    assert errors[1000] / errors[10000] == pytest.approx(10.0, rel=0.3)


def test_two_level_law_commands_only_zero_or_i_max():
    inv = CSDCVariant(BoucWenDamper(), 3, "exact", "two_level")
    inv.reset(np.zeros(3))
    out = inv(np.array([500.0, -500.0, 3000.0]), np.array([1e-3, 1e-3, -1e-3]),
              np.array([0.05, 0.05, -0.05]), np.zeros(3))  # fmt: skip
    assert set(out.tolist()) <= {0.0, 1.5}


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="observer"):
        CSDCVariant(BoucWenDamper(), 1, observer="rk4")
    with pytest.raises(ValueError, match="law"):
        CSDCVariant(BoucWenDamper(), 1, law="bang")
    with pytest.raises(ValueError, match="substeps"):
        CSDCVariant(BoucWenDamper(), 1, observer="euler", substeps=0)
    with pytest.raises(TypeError, match="damper"):
        CSDCVariant(object(), 1)  # type: ignore[arg-type]
