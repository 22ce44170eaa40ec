"""Run controllers over guideway realisations and compute the paper's metrics.

The evaluation loop used by ``evaluate.py`` and the tests: a controller (anything with SB3's
``predict``) drives the native vector env, one vehicle per episode, and the signals in
``info`` are recorded; :func:`episode_metrics` turns them into the paper's vibration-reduction
effect (against the passive run on the same guideway realisations) and ride metrics.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from capsule_env import metrics
from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv

#: Guideway bank for evaluation: held out from training (which uses ``guideway_seed=0``).
EVALUATION_GUIDEWAY_SEED = 2026
#: Guideway bank for choosing among candidates while training (train.py's best model, PPO
#: configurations): held out from training and from the evaluation bank, so that the figures
#: reported on :data:`EVALUATION_GUIDEWAY_SEED` are not selected on.
VALIDATION_GUIDEWAY_SEED = 7
#: Guideway bank for choosing which finished run to ship (experiments/select_policy.py): held
#: out from training, from the validation bank that chose each run's checkpoint (its windows
#: would favour the runs whose checkpoints were chosen on them) and from the evaluation bank.
SELECTION_GUIDEWAY_SEED = 11
#: The unit of each metric of :func:`episode_metrics` (also the suffix of its key).
METRIC_UNITS = {
    "vre_pct": "%",
    "rms_body_acc_m_s2": "m/s^2",
    "wk_rms_body_acc_m_s2": "m/s^2",
    "rms_body_disp_m": "m",
    "rms_bogie_disp_m": "m",
    "max_stroke_m": "m",
    "mean_current_a": "A",
    "coil_power_w": "W",
    "force_tracking_error_rel": "ratio rms(F - F_d) / rms(F_d)",
    "en12299_comfort_index": "EN 12299 mean comfort N, vertical term (dimensionless)",
    "sperling_ride_index": "Sperling ride index Wz (dimensionless)",
    "terminated_episodes": "episodes",
}
RECORDED = (
    "car_body_displacement_m",
    "bogie_displacement_m",
    "car_body_acceleration_m_s2",
    "stroke_m",
    "stroke_rate_m_s",
    "damper_force_n",
    "desired_force_n",
    "current_command_a",
    "coil_current_a",
    "guideway_elevation_m",
)


class Policy(Protocol):
    def predict(
        self, observation: np.ndarray, state: Any = None, episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]: ...  # fmt: skip


@dataclass
class Rollout:
    """Recorded signals, each ``(episodes, steps)``, of one controller in one setting."""

    signals: dict[str, np.ndarray]
    dt_s: float
    terminated: np.ndarray  # (episodes,) bool: hit the bump stop
    action_mode: str

    def select(self, rows: slice | np.ndarray) -> Rollout:
        """The rollout of the episodes ``rows`` only (e.g. one gain candidate's episodes of a
        batch that ran many)."""
        signals = {name: values[rows] for name, values in self.signals.items()}
        return Rollout(signals, self.dt_s, self.terminated[rows], self.action_mode)


def run_episodes(
    policy: Policy,
    env_kwargs: dict[str, Any],
    episodes: int = 10,
    seed: int = 0,
    episode_length_s: float = 10.0,
    seeds: Sequence[int] | None = None,
    recorded: Sequence[str] = RECORDED,
) -> Rollout:
    """Run ``episodes`` episodes (episode ``k``: the single env seeded ``seed + k``, or
    ``seeds[k]`` when ``seeds`` is given; then ``episodes`` is ``len(seeds)``) with one vector
    env, recording the ``info`` signals ``recorded``.

    ``env_kwargs`` are the env's arguments (setting, the controller's needs, overrides; the
    guideway bank is :data:`EVALUATION_GUIDEWAY_SEED` unless they name another).
    After a termination the vehicle's remaining samples repeat its last values.
    """
    if seeds is None:
        seeds = [seed + k for k in range(episodes)]
    episodes = len(seeds)
    kwargs = {"guideway_seed": EVALUATION_GUIDEWAY_SEED, **env_kwargs}
    env = CapsuleSuspensionVectorEnv(num_envs=episodes, episode_length_s=episode_length_s, **kwargs)
    steps = env.batch.max_steps
    # episode k is the single env seeded seeds[k]: each reproducible alone
    obs, _ = env.reset(seed=[int(s) for s in seeds])
    if hasattr(policy, "reset"):
        policy.reset()
    record = {name: np.zeros((episodes, steps)) for name in recorded}
    alive = np.ones(episodes, dtype=bool)
    terminated_any = np.zeros(episodes, dtype=bool)
    start = np.ones(episodes, dtype=bool)
    state = None
    for t in range(steps):
        actions, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        start[:] = False
        obs, _, terminated, truncated, info = env.step(actions)
        for name, column in record.items():
            column[alive, t] = info[name][alive]
            if t > 0:
                column[~alive, t] = column[~alive, t - 1]
        terminated_any |= terminated & alive
        alive &= ~terminated
    env.close()
    return Rollout(record, env.batch.dt, terminated_any, env.config.action_mode)


def episode_metrics(
    rollout: Rollout,
    passive: Rollout | None,
    bands_hz: dict[str, tuple[float, float]] | None = None,
    coil_resistance_ohm: float = metrics.DEFAULT_COIL_RESISTANCE_OHM,
) -> dict[str, Any]:
    """The paper's metrics, averaged over episodes (with the per-episode spread).

    Every key names its unit (see :data:`METRIC_UNITS`):

    - ``vre_pct`` (only with the passive rollout on the same seeds, paper eq. 16): the
      vibration reduction effect in per cent, ``{"body_mode1", "body_mode2", "bogie_mode1",
      "bogie_mode2": %}``;
    - ``rms_body_acc_m_s2`` and ``wk_rms_body_acc_m_s2`` (RMS and ISO 2631-1 Wk-weighted RMS
      car-body acceleration, m/s^2), ``rms_body_disp_m`` and ``rms_bogie_disp_m`` (m),
      ``max_stroke_m`` (largest damper stroke, m), ``mean_current_a`` (mean coil current, A),
      ``coil_power_w`` (W), ``force_tracking_error_rel`` (``rms(F - F_d) / rms(F_d)``, a
      ratio; force mode only);
    - rail ride comfort of the car-body acceleration: ``sperling_ride_index``, the Sperling
      ride index (:func:`capsule_env.metrics.sperling_index`, 0.5-30 Hz, RMS form: independent
      of the record length; present when an episode lasts at least 2 s), and
      ``en12299_comfort_index``, the vertical term ``6 a_ZP95`` of the EN 12299 mean comfort
      index (:func:`capsule_env.metrics.mean_comfort_vertical`, Wb weighting, 5 s windows;
      present when an episode holds at least one 5 s window);
    - ``std``: the spread over episodes of each of those, the VRE ones as
      ``vre_body_mode1_pct`` ...;
    - ``terminated_episodes``: how many episodes hit the bump stop (a count).
    """
    bands = bands_hz or metrics.DEFAULT_BANDS_HZ
    s, dt = rollout.signals, rollout.dt_s
    per_episode = {
        "rms_body_acc_m_s2": metrics.rms(s["car_body_acceleration_m_s2"]),
        "wk_rms_body_acc_m_s2": metrics.wk_weighted_rms(s["car_body_acceleration_m_s2"], dt),
        "rms_body_disp_m": metrics.rms(s["car_body_displacement_m"]),
        "rms_bogie_disp_m": metrics.rms(s["bogie_displacement_m"]),
        "max_stroke_m": np.max(np.abs(s["stroke_m"]), axis=-1),
        "mean_current_a": np.mean(s["coil_current_a"], axis=-1),
        "coil_power_w": metrics.coil_power_w(s["coil_current_a"], coil_resistance_ohm),
    }
    acc, samples = s["car_body_acceleration_m_s2"], s["car_body_acceleration_m_s2"].shape[-1]
    if samples * dt >= 1.0 / metrics.SPERLING_BAND_HZ[0] - 1e-9:  # lines down to 0.5 Hz
        per_episode["sperling_ride_index"] = metrics.sperling_index(acc, dt, combine="rms")
    if samples >= round(metrics.EN12299_WINDOW_S / dt):  # one 5 s window
        per_episode["en12299_comfort_index"] = metrics.mean_comfort_vertical(acc, dt)
    if rollout.action_mode == "force":
        per_episode["force_tracking_error_rel"] = metrics.force_tracking_error(
            s["desired_force_n"], s["damper_force_n"]
        )
    out: dict[str, Any] = {k: float(np.nanmean(v)) for k, v in per_episode.items()}
    out["std"] = {k: float(np.nanstd(v)) for k, v in per_episode.items()}
    if passive is not None:
        vre = {}
        for body, key in (("body", "car_body_displacement_m"), ("bogie", "bogie_displacement_m")):
            for mode, band in bands.items():
                v = metrics.vibration_reduction_effect(
                    passive.signals[key], s[key], dt, band
                )  # fmt: skip
                vre[f"{body}_{mode}"] = float(np.mean(v))
                out["std"][f"vre_{body}_{mode}_pct"] = float(np.std(v))
        out["vre_pct"] = vre
    out["terminated_episodes"] = int(rollout.terminated.sum())
    return out


def minimum_episode_steps(
    dt_s: float, bands_hz: dict[str, tuple[float, float]] | None = None
) -> int:
    """Fewest control steps of ``dt_s`` whose amplitude spectrum has a line in every mode band
    (``bands_hz``, default :data:`capsule_env.metrics.DEFAULT_BANDS_HZ`): the vibration
    reduction effect of :func:`episode_metrics` needs one. Raises ``ValueError`` when a band
    lies above the Nyquist frequency."""
    bands = bands_hz or metrics.DEFAULT_BANDS_HZ
    narrowest = min(hi - lo for lo, hi in bands.values())
    # a resolution 1 / (n dt) no coarser than the narrowest band puts a line in each one
    # below the Nyquist frequency
    for n in range(1, int(np.ceil(1.0 / (max(narrowest, 1e-9) * dt_s))) + 2):
        f = np.fft.rfftfreq(n, dt_s)
        if all(np.any((f >= lo) & (f <= hi)) for lo, hi in bands.values()):
            return n
    raise ValueError(f"mode bands {bands} reach above the Nyquist frequency {0.5 / dt_s:g} Hz")


def check_episode_length(
    episode_length_s: float,
    dt_s: float,
    name: str = "episode_length_s",
    bands_hz: dict[str, tuple[float, float]] | None = None,
) -> int:
    """The number of control steps of an episode of ``episode_length_s`` seconds, checked to
    be long enough for :func:`episode_metrics` (at least one control step of ``dt_s``, and a
    spectral line in every mode band). Raises ``ValueError`` naming ``name`` and the minimum."""
    try:
        length = float(episode_length_s)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number of seconds, got {episode_length_s!r}") from None
    if not (np.isfinite(length) and length > 0.0):
        raise ValueError(f"{name} must be a positive number of seconds, got {episode_length_s!r}")
    steps = int(round(length / dt_s))
    needed = minimum_episode_steps(dt_s, bands_hz)
    if steps < 1:
        raise ValueError(
            f"{name} {length:g} s is shorter than one control step ({dt_s:g} s); the metrics "
            f"need at least {needed * dt_s:.3g} s"
        )
    if steps < needed:
        raise ValueError(
            f"{name} {length:g} s ({steps} control steps) is too short for the spectra of the "
            f"mode bands {dict(bands_hz or metrics.DEFAULT_BANDS_HZ)} Hz: at least "
            f"{needed * dt_s:.3g} s ({needed} steps of {dt_s:g} s) is needed"
        )
    return steps
