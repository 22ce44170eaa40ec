"""CapsuleSuspension-v0: semi-active MR-damper secondary suspension of a Hyperloop capsule.

The single environment and its native vector environment. Both are thin shells over
:class:`capsule_env.engine.batch.CapsuleBatch` (one compiled kernel for 1 or thousands of vehicles).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import Env, spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.error import ResetNeeded
from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space

from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig, check_num_envs, check_seed, observation_bounds
from capsule_env.engine.layout import SIGNAL_NAMES
from capsule_env.envs._actions import real_actions
from capsule_env.envs._compat import AutoresetMode, check_autoreset_mode
from capsule_env.envs._seeds import reseed
from capsule_env.envs.render import check_render_mode, render_vehicle
from capsule_env.envs.spec import LengthSpec

__all__ = [
    "CapsuleSuspensionEnv",
    "CapsuleSuspensionVectorEnv",
    "env_spaces",
    "render_fps",
]


#: Keys ``reset(options=...)`` accepts (none yet: every option is a constructor argument).
RESET_OPTIONS: tuple[str, ...] = ()


def env_spaces(config: EnvConfig) -> tuple[spaces.Box, spaces.Box]:
    """``(action_space, observation_space)`` of one vehicle of an env with these options."""
    action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
    low, high = observation_bounds(config, config.max_current_a)
    return action_space, spaces.Box(low, high, dtype=np.float32)


def render_fps(config: EnvConfig) -> int | float:
    """Frames per second of a real-time video of an env with these options: one frame per
    control step (``render()`` after each step, as Gymnasium's ``RecordVideo`` does), so the
    control rate, ``control_rate_hz`` (an int when it is a whole number)."""
    rate = float(config.control_rate_hz)
    return int(rate) if rate.is_integer() else rate


def _check_options(
    options: dict[str, Any] | None, accepted: tuple[str, ...] = RESET_OPTIONS
) -> None:
    if options is None:
        return
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; accepted: {list(accepted) or 'none'}")


class CapsuleSuspensionEnv(Env[np.ndarray, np.ndarray]):
    """Semi-active MR-damper control of a Hyperloop capsule's secondary suspension.

    ## Description

    A 2-DOF vertical 1/4-car of a capsule vehicle (car body 6000 kg on an air spring and an MR
    damper over a 2400 kg bogie, levitated by an EDS "spring" of 2.25e6 N/m) runs at 810 km/h
    over an irregular guideway (a random FRA-shaped profile scaled to 8 mm peak by default).
    Each control step (200 Hz) the agent chooses the MR damper's action; the goal is ride
    comfort, a small car-body acceleration. The physics, the damper models and their inverses
    follow the capsule-vehicle study (Measurement and Control, 2022, doi:10.1177/00202940221101675;
    the equations with their provenance in ``docs/model.md``): in ``sim`` the
    plant's damper is the very model the controller inverts (the paper's simulation); in
    ``hils`` the plant is the reference Spencer damper with coil lag, sensor noise and a control
    delay while the controller inverts an identified model (the paper's HILS test emulated).

    ## Action Space

    ``Box(-1, 1, (1,), float32)``. Actions outside [-1, 1] are clipped; NaN or infinite actions
    raise ``ValueError``.

    | action_mode | meaning of ``a`` |
    |-------------|------------------|
    | ``"force"`` (default) | desired damper force ``F_d = a * max_force_n`` (N), turned into a coil current by ``inverse_model`` (Bi-exponential closed form, CSDC for Bouc-Wen, or tanh), using the measured stroke and stroke rate; requests the damper cannot make become 0 A or ``i_max`` |
    | ``"current"`` | coil current command ``i = (a + 1) / 2 * i_max`` (A), ``i_max`` = 1.5 A |

    ## Observation Space

    ``Box(low, high, (n,), float32)`` in SI units (no scaling: wrap in ``VecNormalize`` or
    ``NormalizeObservation`` for learning), bounded by generous physical limits at which the
    sensors saturate (observations are clipped to them): accelerations +-100 m/s^2, stroke +-2 x
    ``stroke_limit_m``, rates +-10 m/s, displacements and elevation +-1 m, current
    ``[0, i_max]``. ``observation="sensors"`` (default), what a real vehicle measures (with noise
    in ``hils``):

    | index | observation | unit |
    |-------|-------------|------|
    | 0 | car body vertical acceleration | m/s^2 |
    | 1 | bogie vertical acceleration | m/s^2 |
    | 2 | damper stroke ``x = z_c - z_b`` | m |
    | 3 | stroke rate ``v`` | m/s |
    | 4 | last coil current command | A |

    ``observation="full_state"`` (every state; with measurement noise where ``sensor_noise`` > 0,
    as in ``hils``, so controllers that read states are not given what sensors could not):

    | index | observation | unit |
    |-------|-------------|------|
    | 0 | car body displacement ``z_c`` | m |
    | 1 | car body velocity | m/s |
    | 2 | bogie displacement ``z_b`` | m |
    | 3 | bogie velocity | m/s |
    | 4 | guideway elevation under the bogie ``z_g`` | m |
    | 5 | car body acceleration | m/s^2 |
    | 6 | bogie acceleration | m/s^2 |
    | 7 | stroke | m |
    | 8 | stroke rate | m/s |
    | 9 | actual coil current (after the coil lag) | A |

    ``observation="measured"``, what a capsule's own sensors read (with noise in ``hils``) and
    the on-board estimates of the absolute velocities, computed inside the env at the control
    rate from those same noisy accelerometers (band-limited integration, ``H(s) = s / (s^2 + 2
    zeta w_c s + w_c^2)``: corner ``velocity_estimator_corner_hz`` 0.1 Hz and damping
    ``velocity_estimator_damping`` 1/sqrt(2) by default; about 12 % RMS error on the body
    velocity and 16 % on the bogie's in ``hils``, no drift):

    | index | observation | unit |
    |-------|-------------|------|
    | 0 | car body vertical acceleration (accelerometer) | m/s^2 |
    | 1 | bogie vertical acceleration (accelerometer) | m/s^2 |
    | 2 | damper stroke (LVDT) | m |
    | 3 | stroke rate | m/s |
    | 4 | levitation gap change ``z_b - z_g`` (gap sensor) | m |
    | 5 | coil current (the driver's measurement) | A |
    | 6 | last coil current command | A |
    | 7 | car body absolute velocity estimate | m/s |
    | 8 | bogie absolute velocity estimate | m/s |

    **Guideway preview** (any observation set, ``preview_points`` > 0): ``preview_points``
    more columns, ``preview_ahead_<k>`` (m, ``k = 1 .. preview_points``), the surveyed guideway
    elevation ``k * preview_horizon_s / preview_points`` seconds ahead of the bogie, relative to
    the surveyed elevation under it now. A Hyperloop tube is surveyed infrastructure and the
    propulsion system tracks the capsule's position, so this is a map lookup, not a sensor.
    It is looked up in a survey map (the true profile plus a long-wavelength map offset of
    standard deviation ``survey_offset_m``, 50-500 m wavelengths, and a short-wavelength error
    ``survey_noise_m``, 2-50 m; the map belongs to the guideway bank) at the vehicle's
    estimated position (the true one plus an episode-constant error drawn with standard
    deviation ``position_error_m``). Defaults (all [reconstructed]): 0.5 mm, 0.1 mm, 0.05 m.

    **Trips** (``speed_profile="trip"``, any observation set): two more columns after the set's
    own (before any preview), ``speed_m_s`` (m/s) and ``longitudinal_acceleration_m_s2``
    (m/s^2, > 0 speeding up), exact (the propulsion control knows them). With trips the
    preview looks ahead at the current speed.

    ## Rewards

    A ride-comfort cost with stroke and energy terms, per step::

        r = -( w_acc (a_c / a_ref)^2 + w_stroke (x / x_ref)^2 + w_energy (i / i_max)^2
               + w_vel (z_c' / v_ref)^2 ) - bump_stop_penalty * [|x| > stroke_limit_m]

    with ``a_c`` the car-body acceleration (``reward_acceleration_filter="wk"``: passed through
    the ISO 2631-1 Wk weighting as a causal filter, so that the acceleration term is the
    per-step square of the reported ``wk_rms_body_acc_m_s2``; ``info["reward_acceleration_m_s2"]``
    holds what the reward read), ``x`` the stroke, ``i`` the applied current
    (coil power is proportional to ``i^2``) and ``z_c'`` the car-body velocity (a Skyhook-like
    term that weighs the body mode). Defaults: ``w_acc = 1``, ``a_ref = 0.5 m/s^2``,
    ``w_stroke = 0.1``, ``x_ref = 0.02 m``, ``w_energy = 0.01``, ``w_vel = 0``,
    ``v_ref = 0.05 m/s``, penalty 100. Each term is in ``info`` (``cost_acceleration``,
    ``cost_stroke``, ``cost_energy``, ``cost_velocity``).

    ## Starting State

    The vehicle at rest in static equilibrium over the guideway's first elevation (both masses
    displaced by ``z_g(0)``), damper states and coil current zero. Each reset draws a new
    guideway window (a random stretch of one of ``guideway_bank_size`` long profiles generated
    from ``guideway_seed``, rescaled to the peak), and, if enabled, new vehicle parameters and
    speed. The reset observation is exact (no noise).

    ## Episode End

    - Truncation: after ``episode_length_s * control_rate_hz`` steps (10 s = 2000 steps by
      default); the env truncates itself, so the length follows its arguments in
      ``gymnasium.make``, ``make_vec`` and the SB3 ``VecEnv`` alike (``env.spec.max_episode_steps``
      reports it; a ``max_episode_steps`` passed to ``gymnasium.make`` adds a ``TimeLimit``
      and the earlier of the two ends the episode).
    - Termination: the stroke passes the bump stop ``|x| > stroke_limit_m`` (60 mm default).
    - ``step`` before ``reset``, or after an episode ended, raises
      ``gymnasium.error.ResetNeeded``.

    ## Info

    Every step: the physical signals ``car_body_displacement_m``, ``bogie_displacement_m``,
    velocities, accelerations, ``stroke_m``, ``stroke_rate_m_s``, ``damper_force_n``,
    ``desired_force_n`` (0 in current mode), ``current_command_a``, ``coil_current_a``,
    ``guideway_elevation_m``, the reward terms, and the on-board velocity estimates
    (``car_body_velocity_estimate_m_s``, ``bogie_velocity_estimate_m_s``), and the car-body
    acceleration the reward read (``reward_acceleration_m_s2``).

    ## Arguments

    ``gymnasium.make("CapsuleSuspension-v0", **kwargs)`` with any field of
    :class:`capsule_env.engine.config.EnvConfig`, each validated (a bad value raises ``ValueError``
    naming the argument and the accepted values):

    - ``action_mode``: ``"force"`` | ``"current"``.
    - ``inverse_model``: ``"bi_exponential"`` | ``"csdc"`` | ``"tanh"`` (force mode).
    - ``setting``: ``"sim"`` | ``"hils"``; ``damper`` overrides the plant's damper
      (``"reference"``, ``"bouc_wen"``, ``"bi_exponential"``, ``"tanh"``, ``"passive"``).
    - HILS knobs, each separate (None = the setting's value): ``coil_time_constant_s``
      (hils 1/190 s), ``sensor_noise`` (multiplier of the per-channel noise levels, hils 1),
      ``control_delay_steps`` (hils 1).
    - Guideway: ``guideway`` (``"random"``, ``"sine"``, ``"swept_sine"``, ``"bump"``,
      ``"step"``), ``guideway_params`` (dict of :class:`capsule_env.guideway.GuidewayParams`
      fields, e.g. ``{"peak_m": 0.008}``), ``speed_kmh`` (810), ``guideway_seed`` (0),
      ``guideway_bank_size`` (16).
    - Timing: ``control_rate_hz`` (200), ``episode_length_s`` (10), ``substeps`` (auto).
    - ``observation``: ``"sensors"`` | ``"full_state"`` | ``"measured"``; the velocity
      estimator of ``"measured"``: ``velocity_estimator_corner_hz`` (0.1),
      ``velocity_estimator_damping`` (1/sqrt(2)).
    - Guideway preview: ``preview_points`` (0: none; at most 64), ``preview_horizon_s`` (0.5),
      and the survey's errors ``survey_offset_m`` (5e-4), ``survey_noise_m`` (1e-4),
      ``position_error_m`` (0.05).
    - Reward: ``reward_acceleration_weight``, ``reward_stroke_weight``,
      ``reward_energy_weight``, ``reward_velocity_weight``, ``acceleration_scale_m_s2``,
      ``stroke_scale_m``, ``velocity_scale_m_s``, ``stroke_limit_m``, ``bump_stop_penalty``,
      ``reward_acceleration_filter`` (``"none"`` | ``"wk"``);
      ``max_force_n`` (8 kN, force-mode scale).
    - The vehicle: ``vehicle`` (a registered model of :mod:`capsule_env.vehicles`, default
      ``"quarter_car"``).
    - Overrides: ``vehicle_params``, ``damper_params`` (plant), ``inverse_params`` (the model
      the controller inverts), each a dict of dataclass fields.
    - Domain randomisation per episode: ``vehicle_randomization`` (relative half-width of a
      uniform factor on each of m_c, m_b, k_s, k_p), ``speed_range_kmh`` (low, high) and
      ``payload_range`` (low, high: a uniform change of the car body mass, as a fraction, e.g.
      ``(-0.3, 0.4)``).
    - The operating envelope (:mod:`capsule_env.envelope.options`, docs/model.md section 13; each off by
      default): ``levitation`` (``"fixed"`` | ``"eds"``: the levitation's stiffness and damping
      follow the speed, ``levitation_params`` :class:`capsule_env.envelope.levitation.EdsParams`
      fields), ``speed_profile`` (``"constant"`` | ``"trip"``: each episode a window of a trip
      from lift-off to cruise and back, ``trip_params`` :class:`capsule_env.envelope.trips.TripParams`
      fields), ``spans`` (``"none"`` | ``"continuous"`` | ``"simply_supported"``: the tube's
      sag between pylons and their settlement added to the guideway, ``span_params``
      :class:`capsule_env.guideway.spans.SpanParams` fields but ``shape``), ``magnet_length_m``
      (None: the guideway read at a point; a length in [0.001, 50] m: the plant reads it averaged
      over the magnet, :mod:`capsule_env.envelope.magnet`, the preview's survey map the true one).
    - ``render_mode``: ``"rgb_array"``: ``render()`` draws the vehicle now, one frame per
      control step; ``metadata["render_fps"]`` is this env's control rate (``control_rate_hz``,
      200 by default, set per instance), so a video written by Gymnasium's ``RecordVideo`` (or
      SB3's ``VecVideoRecorder``) plays in real time.

    An unknown argument raises :class:`capsule_env.engine.config.UnexpectedArgumentError`, both a
    ``TypeError`` worded as Python's (``... got an unexpected keyword argument 'frameskip'``,
    what TorchRL's ``GymEnv`` expects) and a ``ValueError``, listing the accepted names.

    ## Version History

    - v0: initial release; later additions keep v0 (new options default to the old behaviour):
      the ``measured`` observation set and its velocity estimator; per-vehicle substeps; the
      branch blend of the sign-of-stroke damper models; independent seed streams per vehicle;
      the guideway preview; the Wk-weighted reward acceleration; the operating envelope
      (EDS levitation against speed, trips, tube spans, payload).
    """

    #: Class defaults; each instance sets ``render_fps`` to its own control rate.
    metadata = {"render_modes": ["rgb_array"], "render_fps": 200}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        check_render_mode(render_mode)
        self.config = EnvConfig.from_kwargs(
            "CapsuleSuspensionEnv.__init__", ("render_mode",), **kwargs
        )
        self.metadata = {**type(self).metadata, "render_fps": render_fps(self.config)}
        self.render_mode = render_mode
        # infos are copied into a dict every step: no fresh signal arrays needed
        self._batch = CapsuleBatch(self.config, 1, fresh_signals=False)
        self.action_space, self.observation_space = env_spaces(self.config)
        self._needs_reset = True

    spec = LengthSpec.spec
    _spec: EnvSpec | None = None

    @property
    def batch(self) -> CapsuleBatch:
        """The underlying one-vehicle simulation (state, parameters, signals)."""
        return self._batch

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: ``(observation, info)``. ``seed`` (an integer in ``[0, 2**63)``)
        re-seeds the vehicle's stream; ``options`` accepts no key yet (any raises
        ``ValueError``)."""
        if seed is not None:
            seed = check_seed("seed", seed)  # a Python int: Gymnasium refuses numpy's
        _check_options(options)
        super().reset(seed=seed)
        if seed is not None:
            self._batch.seed(seed)
        self._batch.reset()
        self._needs_reset = False
        return self._batch.obs[0].copy(), self._info()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control step: ``(observation, reward, terminated, truncated, info)``.

        ``action`` has shape ``(1,)`` (or is a number) and is clipped to [-1, 1]; a wrong
        shape, NaN or infinity raises ``ValueError``, complex numbers, strings or other
        non-numbers ``TypeError``.
        Before :meth:`reset`, or after the episode ended, raises
        ``gymnasium.error.ResetNeeded``.
        """
        if self._needs_reset:
            raise ResetNeeded(
                "call reset() before step(): the episode has not started or has ended"
            )
        batch = self._batch
        batch.step_one(_single_action(action))
        terminated = bool(batch.terminated[0])
        truncated = bool(batch.step_count[0] >= batch.max_steps)
        self._needs_reset = terminated or truncated
        return (
            batch.obs[0].copy(),
            float(batch.reward[0]),
            terminated,
            truncated,
            self._info(),
        )

    def _info(self) -> dict[str, Any]:
        # signals has N_SIGNALS = len(SIGNAL_NAMES) rows (layout); zip's strict check would
        # cost a sixth of this dict's 1.1 us
        return dict(zip(SIGNAL_NAMES, self._batch.signals[:, 0].tolist()))  # noqa: B905

    def render(self) -> np.ndarray | None:
        """A side view of the vehicle (RGB array) with ``render_mode="rgb_array"``, else None."""
        if self.render_mode != "rgb_array":
            return None
        return render_vehicle(self._batch, 0)


def _single_action(action: Any) -> float:
    """The one number of a single env's action: shape (1,) (the action space) or a scalar."""
    if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
        return float(action[0])  # the common case, first
    if isinstance(action, (float, int, np.floating, np.integer)) and not isinstance(action, bool):
        return float(action)
    a = real_actions(action, "action")  # not complex numbers, strings or objects
    if a.shape not in ((1,), ()):
        raise ValueError(f"action must have shape (1,), got shape {a.shape}")
    return float(a.reshape(-1)[0])


class CapsuleSuspensionVectorEnv(VectorEnv):
    """Native batched ``CapsuleSuspension-v0``: ``num_envs`` vehicles in one compiled kernel.

    Same dynamics, spaces, reward and arguments as :class:`CapsuleSuspensionEnv`, plus
    ``num_envs``, ``max_episode_steps`` (the earlier of it and the env's own length ends an
    episode, as ``TimeLimit`` on the single env) and ``autoreset_mode``. ``reset(seed=s)``
    gives the vehicles the independent streams ``numpy.random.SeedSequence(s).spawn(num_envs)``
    (vehicle 0 is the single env seeded ``s``; two different seeds share no stream);
    ``reset(seed=[s_0, ..., s_{N-1}])`` gives vehicle ``n`` the stream of the single env seeded
    ``s_n``, and an ``s_n`` of None leaves vehicle ``n``'s stream as it is (Gymnasium's
    ``list[int | None]``, as ``SyncVectorEnv``). ``info`` is a dict of arrays (one entry per vehicle, fresh arrays every step) with
    Gymnasium's ``_key`` masks. Actions: shape ``(num_envs, 1)`` (the action space) or
    ``(num_envs,)``. Batches of 64 or more are split across threads (:mod:`capsule_env.engine.kernels`).

    ``autoreset_mode`` (``gymnasium.vector.AutoresetMode`` or its string value, also through
    ``gymnasium.make_vec(..., vectorization_mode="vector_entry_point", autoreset_mode=...)``;
    ``self.autoreset_mode`` and ``metadata["autoreset_mode"]`` report it), with Gymnasium's
    conventions (those of ``SyncVectorEnv``):

    - ``NEXT_STEP`` (default): the step *after* an episode ends resets that vehicle and returns
      its first observation with reward 0 and ``terminated = truncated = False``; the action
      given for it in that step is ignored.
    - ``SAME_STEP``: the step that ends an episode resets the vehicle at once and returns the
      new episode's first observation, with the episode's reward, ``terminated`` and
      ``truncated``; the last observation is in ``info["final_obs"]`` (an object array, None
      for the vehicles that did not end) and the last step's info in ``info["final_info"]``
      (a dict of arrays), masked by ``info["_final_obs"]`` and ``info["_final_info"]``; the
      other entries of ``info`` hold the reset vehicle's reset info.
    - ``DISABLED``: no automatic reset. Reset the finished vehicles with
      ``reset(options={"reset_mask": mask})`` (a boolean array of shape ``(num_envs,)``: only
      those vehicles start new episodes; the others keep their state and observation rows; the
      info holds the reset vehicles' entries only). ``step`` while a vehicle's episode has
      ended and it was not reset raises ``gymnasium.error.ResetNeeded`` naming the vehicles
      (Gymnasium's ``SyncVectorEnv`` asserts).

    The modes only move where the resets fall: for the same seed and the same actions within
    each episode, every vehicle runs the same episodes, bit for bit, in all three (and as the
    single env, or Gymnasium's ``SyncVectorEnv`` over it in the same mode, with
    ``seed=[s_0, ..., s_{N-1}]``). ``options={"reset_mask": mask}`` is accepted in every mode
    (after a first full ``reset``); with ``seed``, the masked vehicles get the streams a full
    reset with that seed would give them.
    """

    #: Class defaults; each instance sets ``render_fps`` (its control rate) and
    #: ``autoreset_mode`` (its own).
    metadata = {
        "render_modes": ["rgb_array"],
        "render_fps": 200,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs: Any,
    ) -> None:
        check_render_mode(render_mode)
        self.config = EnvConfig.from_kwargs(
            "CapsuleSuspensionVectorEnv.__init__",
            ("num_envs", "render_mode", "max_episode_steps", "autoreset_mode"),
            **kwargs,
        )
        self.num_envs = check_num_envs(num_envs)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        self.metadata = {
            **type(self).metadata,
            "render_fps": render_fps(self.config),
            "autoreset_mode": self.autoreset_mode,
        }
        self.render_mode = render_mode
        self._batch = CapsuleBatch(self.config, self.num_envs)
        if max_episode_steps is not None:
            if isinstance(max_episode_steps, bool) or not isinstance(
                max_episode_steps, (int, np.integer)
            ) or max_episode_steps < 1:  # fmt: skip
                raise ValueError(
                    f"max_episode_steps must be an integer >= 1, got {max_episode_steps!r}"
                )
            # As Gymnasium's TimeLimit on the single env: the earlier of the two limits.
            self._batch.max_steps = min(self._batch.max_steps, int(max_episode_steps))
        self.single_action_space, self.single_observation_space = env_spaces(self.config)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        # NEXT_STEP: vehicles to reset at the next step; DISABLED: vehicles that must be reset
        # (reset_mask) before the next step; SAME_STEP: always False.
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._mask = np.ones(self.num_envs, dtype=bool)
        self._needs_reset = True

    @property
    def batch(self) -> CapsuleBatch:
        return self._batch

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        _check_options(options, ("reset_mask",))
        mask = None if options is None else options.get("reset_mask")
        if mask is not None:
            return self._reset_masked(_check_reset_mask(mask, self.num_envs), seed)
        # an int or a list of num_envs ints, None keeping a vehicle's stream (Gymnasium's)
        reseed(self._batch, seed, self.num_envs)
        super().reset(seed=int(seed) if isinstance(seed, (int, np.integer)) else None)
        self._batch.reset()
        self._autoreset[:] = False
        self._needs_reset = False
        return self._batch.obs.copy(), self._infos()

    def _reset_masked(
        self, mask: np.ndarray, seed: int | list[int] | None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """``reset(options={"reset_mask": mask})``: new episodes for the masked vehicles only."""
        if self._needs_reset:
            raise ResetNeeded(
                "call reset() without options['reset_mask'] first: a partial reset continues "
                "a running batch"
            )
        batch = self._batch
        if seed is not None:
            reseed(batch, seed, self.num_envs, mask)  # validates the seed(s)
            super().reset(seed=int(seed) if isinstance(seed, (int, np.integer)) else None)
        batch.detach_signals()  # the last step's info arrays keep their values
        batch.reset(mask)
        self._autoreset[mask] = False
        return batch.obs.copy(), self._infos(mask)

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if self._needs_reset:
            raise ResetNeeded("call reset() before step()")
        mode = self.autoreset_mode
        if mode is AutoresetMode.DISABLED and self._autoreset.any():
            raise ResetNeeded(
                f"the episodes of vehicles {np.flatnonzero(self._autoreset).tolist()} have "
                "ended and autoreset_mode is DISABLED: reset them with "
                "reset(options={'reset_mask': mask}) before step()"
            )
        batch = self._batch
        a = real_actions(actions)
        if a.shape not in ((self.num_envs, 1), (self.num_envs,)):
            raise ValueError(f"actions must have shape ({self.num_envs}, 1), got {a.shape}")
        batch.step(a.reshape(self.num_envs))
        reward = batch.reward.copy()
        terminated = batch.terminated.copy()
        truncated = batch.step_count >= batch.max_steps
        if mode is AutoresetMode.NEXT_STEP and self._autoreset.any():
            mask = self._autoreset
            batch.reset(mask)
            reward[mask] = 0.0
            terminated[mask] = False
            truncated[mask] = False
        ended = terminated | truncated
        if mode is AutoresetMode.SAME_STEP:
            if ended.any():
                return self._same_step_reset(ended, reward, terminated, truncated)
        else:
            self._autoreset = ended
        return batch.obs.copy(), reward, terminated, truncated, self._infos()

    def _same_step_reset(
        self, ended: np.ndarray, reward: np.ndarray, terminated: np.ndarray, truncated: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """SAME_STEP: reset the vehicles whose episodes just ended; their last observation and
        info go to ``info["final_obs"]`` and ``info["final_info"]`` (Gymnasium's layout)."""
        batch = self._batch
        ids = np.flatnonzero(ended)
        final_obs = np.full(self.num_envs, None, dtype=object)
        for n in ids:
            final_obs[n] = batch.obs[n].copy()
        final_info = self._infos(ended, batch.signals)  # copies of the rows, before the reset
        batch.reset(ended)  # writes the reset vehicles' rows of this step's signal buffer
        infos = self._infos()
        infos["final_obs"], infos["_final_obs"] = final_obs, ended.copy()
        infos["final_info"], infos["_final_info"] = final_info, ended.copy()
        return batch.obs.copy(), reward, terminated, truncated, infos

    def _infos(
        self, mask: np.ndarray | None = None, columns: np.ndarray | None = None
    ) -> dict[str, Any]:
        """The info dict: every vehicle's signals (rows of this step's fresh buffer, no copy),
        or, with ``mask``, new arrays holding the masked vehicles' values (0 elsewhere) under
        the mask, as Gymnasium's vector envs build the info of some sub-envs only."""
        columns = self._batch.signals if columns is None else columns
        infos: dict[str, Any] = {}
        if mask is None:
            for j, name in enumerate(SIGNAL_NAMES):
                infos[name] = columns[j]
                infos["_" + name] = self._mask
            return infos
        mask = mask.copy()
        for j, name in enumerate(SIGNAL_NAMES):
            values = np.zeros(self.num_envs)
            values[mask] = columns[j, mask]
            infos[name] = values
            infos["_" + name] = mask
        return infos

    def render(self) -> tuple[np.ndarray, ...] | None:
        if self.render_mode != "rgb_array":
            return None
        return tuple(render_vehicle(self._batch, n) for n in range(self.num_envs))


def _check_reset_mask(mask: Any, num_envs: int) -> np.ndarray:
    """``options["reset_mask"]`` checked: a boolean numpy array of shape ``(num_envs,)`` with
    at least one True (Gymnasium's rules), returned as a copy."""
    expected = f"a numpy bool array of shape ({num_envs},) with at least one True"
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
        what = type(mask).__name__ if not isinstance(mask, np.ndarray) else f"dtype {mask.dtype}"
        raise TypeError(f"options['reset_mask'] must be {expected}, got {what}")
    if mask.shape != (num_envs,) or not mask.any():
        raise ValueError(
            f"options['reset_mask'] must be {expected}, got shape {mask.shape} with "
            f"{int(mask.sum())} True"
        )
    return mask.copy()
