"""Registered tasks: env ids a benchmark can name, each with its card.

``CapsuleSuspension-v0`` is the env with every option open (its defaults are the paper's
``sim`` setting). The tasks below fix the options a result depends on, so that a score quoted
for ``CapsuleRide-v0`` means one thing:

==============================  =============================================================
``CapsuleSuspension-v0``        the paper's setting: ``sim`` plant (ideal sensors, no delay),
                                three accelerometer/stroke sensors as the observation
``CapsuleRide-v0``              the realistic ride task: ``hils`` plant (coil lag, sensor noise,
                                one-step delay) and the ``measured`` signals a capsule has
``CapsuleRidePreview-v0``       the same with the surveyed guideway ahead (32 points, 0.5 s)
``CapsuleTrip-v0``              the ride task across the operating envelope: EDS levitation
                                against speed, 10 s windows of a trip from lift-off (150 km/h)
                                to cruise (1000 km/h), the tube's spans on pylons, the payload
                                randomised (-30 % to +40 % of the car body mass)
``CapsuleHalfRide-v0``          the half-car capsule (pitch, two bogies, two dampers) on the ride
                                task: ``hils``, measured signals; scored at the floor's front,
                                centre and rear (``DECLARED_TASKS``)
``CapsuleHalfRidePreview-v0``   the same with the surveyed guideway ahead of each bogie
==============================  =============================================================

Every task keeps the env's reward (docs/env.md) and is reported with the ISO 2631-1
Wk-weighted RMS car-body acceleration (m/s^2), mean over the evaluation bank's guideway seeds
1000..1009 (``evaluate.py``'s default), and the normalised score ``(passive - x) / (passive -
oracle)``: 0 is the passive damper, 1 the clairvoyant oracle on the same episodes (a
multi-start local search that reads the whole guideway: a reference, not a proven limit).
The reference scores of each card (passive, the best tuned classical law, the shipped policy,
the oracle) are read from ``docs/figures/evaluation.json``, the file the results page is built
from (the trip and half-car tasks' from their own files, ``Task.results``), by
:mod:`capsule_env.evaluation.task_cards` (``python -m capsule_env.evaluation.task_cards
docs/tasks.md``; a test checks the page is in sync).

Names and versions follow Gymnasium's conventions: a change of a task's options or of the
physics under it gets a new version; the old id keeps its meaning.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "Task",
    "TASKS",
    "DECLARED_TASKS",
    "register_tasks",
    "task_named",
    "normalised_score",
    "reference_law_for",
]


@dataclass(frozen=True)
class Task:
    """One registered task: its id, what it models, what the agent reads, its env options,
    the evaluation's names of its reference controllers, the evaluation file (under
    docs/figures/) its card's scores come from, and which law to compare against and why
    (``use``), the README's one-line description of it (``headline``), the laws designed
    for it that ``evaluate.py --task`` adds to its default controllers (``own_laws``), and
    its card's reported metric where it is not the 1/4-car's car-body Wk (``metric``)."""

    env_id: str
    summary: str
    reads: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    setting: str = "sim"
    best_classical: str = ""
    shipped_policy: str = ""
    results: str = "evaluation.json"
    use: str = ""
    headline: str = ""
    own_laws: tuple[str, ...] = ()
    metric: str = ""


# Which law to compare against on each task, and why (printed on the task cards).
_USE_PAPER = (
    "to reproduce the paper, its on-off Skyhook with each inverse (`skyhook-biexp`, "
    "`skyhook-csdc`); as the baseline for a new controller, `lqr-clipped-biexp-meas`: the "
    "lowest Wk of the laws on measurable signals in this setting, a gain vector and a clip, no "
    "solver."
)
_USE_RIDE = (
    "`mpc-biexp-meas` for a headline comparison: the lowest Wk on these signals (0.994 x the "
    "clipped LQR), a 50 ms plan solved at every step in Python (median 0.15 ms). "
    "`lqr-clipped-biexp-meas` where cost matters, or as the law a residual policy rides on: "
    "0.6 % behind at the cost of a dot product."
)
_USE_PREVIEW = (
    "`preview-mpc-biexp-meas` (the lowest Wk), or `preview-lq-biexp-meas` 0.4 % behind at the "
    "cost of a gain vector over the state and the preview. Both read 1 s of survey preview, "
    "twice the task's 0.5 s: a policy limited to the task's observation meets a reference "
    "that reads more than it does."
)
_USE_TRIP = (
    "`mpc-biexp-meas` (the lowest Wk without preview). The law designed for this task, "
    "`lqr-sched-biexp-meas` (the clipped LQR with gains scheduled on speed and the EDS "
    "levitation), is level with it on these 10 episodes (0.3859) but 1.007 x the fixed-gain LQR "
    "on 50 other held-out ones (docs/controllers.md): evaluate.py runs it on this task, compare "
    "against the MPC."
)


TASKS: tuple[Task, ...] = (
    Task("CapsuleSuspension-v0",
         "The paper's setting: the sim plant (ideal sensors, no delay, no coil lag), 810 km/h, "
         "the random guideway; every option of the env open.",
         "car-body and bogie accelerations and the stroke (observation='sensors')",
         {}, "sim", "lqr-clipped-biexp-meas", "", use=_USE_PAPER,
         headline="the paper's setting: ideal sensors, every option open"),
    Task("CapsuleRide-v0",
         "The realistic ride task: the hils plant (coil lag, sensor noise, one control step of "
         "delay) with the signals a capsule measures.",
         "the measured signals: accelerations, stroke, gap, their on-board velocity estimates "
         "and the applied current (observation='measured')",
         {"setting": "hils", "observation": "measured"}, "hils",
         "mpc-biexp-meas", "residual-ppo-mpc", use=_USE_RIDE,
         headline="the `hils` plant, measured signals"),
    Task("CapsuleRidePreview-v0",
         "The ride task with the surveyed guideway ahead (32 points over 0.5 s, survey offset "
         "and noise as the env's defaults).",
         "the measured signals and the preview of the surveyed guideway",
         {"setting": "hils", "observation": "measured", "preview_points": 32,
          "preview_horizon_s": 0.5}, "hils", "preview-mpc-biexp-meas", "ppo-preview",
         use=_USE_PREVIEW,
         headline="the ride task + 0.5 s of surveyed guideway ahead"),
    Task("CapsuleTrip-v0",
         "The ride task across the operating envelope: EDS levitation whose stiffness and "
         "damping follow the speed, each episode a 10 s window of a trip (lift-off at 150 "
         "km/h, 1.0 m/s^2 to a 1000 km/h cruise, braking), the tube's sag between pylons "
         "every 30 m, the payload drawn per episode (-30 % to +40 % of the car body mass).",
         "the measured signals, the speed and the longitudinal acceleration",
         {"setting": "hils", "observation": "measured", "levitation": "eds",
          "speed_profile": "trip", "spans": "continuous", "payload_range": (-0.3, 0.4)},
         "hils", "mpc-biexp-meas", "residual-ppo-mpc-trip", "evaluation-CapsuleTrip-v0.json",
         use=_USE_TRIP, own_laws=("lqr-sched-biexp-meas",),
         headline="the ride task across a trip: EDS levitation against speed, spans, payload"),
)  # fmt: skip

#: Tasks over a declared vehicle of another form than the 1/4-car's: their env is
#: ``DeclaredVehicleEnv`` (``DeclaredVectorEnv`` batched), their evaluation
#: :mod:`capsule_env.evaluation.half_car` (and ``half_car_preview``; ``docs/half-car.md``),
#: which ``evaluate.py --task`` runs (the JSON's layout and headline ``wk_rms_body_acc_m_s2``
#: the 1/4-car tasks'); carded in ``docs/tasks.md`` as the others.
_METRIC_HALF = (
    "ISO 2631-1 Wk-weighted RMS vertical acceleration of the car body's floor at three points, "
    "over the front bogie, at the centre of mass and over the rear bogie, and their mean (the "
    "headline `wk_rms_body_acc_m_s2`, the name the other tasks use): a passenger sits anywhere "
    "along the body, and the ends, where the pitch adds to the heave, ride worst (passive: "
    "front 0.31, centre 0.15, rear 0.33 m/s²). Beside it the pitch acceleration's We-weighted "
    "RMS (rad/s², ISO 2631-1's weighting for rotational vibration; the seat's factor 0.40 for "
    "pitch not applied), `we_rms_pitch_rad_s2` (docs/half-car.md)"
)
_USE_HALF = (
    "`wheelbase-mpc-biexp-meas`, the half-car's semi-active MPC with the wheelbase preview (the "
    "rear contact's input estimated from the front bogie's measured signals): the lowest Wk on "
    "these signals, a 50 ms plan of both dampers solved at every step (under 1 ms a step in "
    "Python); the shipped residual policy rides on it. `lqr-clipped-biexp-meas`, one tuned "
    "quarter-car clipped LQR per bogie, where cost matters: 1.007 x at the cost of a gain "
    "vector per bogie (the coupled half-car LQR 1.011 x, the wheelbase-preview LQ 1.007 x)."
)
_USE_HALF_PREVIEW = (
    "`survey-preview-lq-biexp-meas`, the half-car's discrete LQ plus Tomizuka's preview gains "
    "on each bogie's own survey, weights tuned on the training bank: 0.959 x the best law "
    "without the survey (`wheelbase-mpc-biexp-meas`; every row without it is its "
    "`CapsuleHalfRide-v0` row) and 0.953 x the per-bogie clipped LQR, gain matrices and a "
    "clip, no solver."
)
DECLARED_TASKS: tuple[Task, ...] = (
    Task("CapsuleHalfRide-v0",
         "The half-car capsule on the ride task: car body heave and pitch on two bogies, two "
         "MR dampers (action shape (2,)), the hils plant (Spencer's damper with its coil lag, "
         "sensor noise, one control step of delay), 810 km/h, the random guideway; the rear "
         "bogie meets the front's guideway (a + b) / v = 89 ms later.",
         "per bogie: stroke, stroke rate, the accelerations over and of the bogie, the "
         "levitation gap, the on-board velocity estimates and the last current command "
         "(observation='measured')",
         {"vehicle": "half_car", "setting": "hils", "observation": "measured"}, "hils",
         "wheelbase-mpc-biexp-meas", "residual-ppo-mpc-half-car",
         "evaluation-CapsuleHalfRide-v0.json",
         use=_USE_HALF, metric=_METRIC_HALF,
         headline="the half-car capsule: pitch, two bogies, two dampers (`hils`, measured)"),
    Task("CapsuleHalfRidePreview-v0",
         "The half-car ride task with the surveyed guideway ahead of each bogie (32 points over "
         "0.5 s per bogie, each from its own bogie; survey offset and noise as the env's "
         "defaults).",
         "the measured signals of both bogies and each bogie's preview of the surveyed guideway",
         {"vehicle": "half_car", "setting": "hils", "observation": "measured",
          "preview_points": 32, "preview_horizon_s": 0.5}, "hils",
         "survey-preview-lq-biexp-meas", "", "evaluation-CapsuleHalfRidePreview-v0.json",
         use=_USE_HALF_PREVIEW, metric=_METRIC_HALF,
         headline="the half-car ride task + 0.5 s of surveyed guideway ahead of each bogie"),
)  # fmt: skip

ENTRY_POINT = "capsule_env.envs.capsule_suspension:CapsuleSuspensionEnv"
VECTOR_ENTRY_POINT = "capsule_env.envs.capsule_suspension:CapsuleSuspensionVectorEnv"
DECLARED_ENTRY_POINT = "capsule_env.envs.declared_vehicle:make_suspension_env"
DECLARED_VECTOR_ENTRY_POINT = "capsule_env.envs.declared_vector:make_suspension_vector_env"


def task_named(env_id: str) -> Task:
    """The task registered as ``env_id`` (``ValueError`` naming the ids otherwise)."""
    for task in TASKS:
        if task.env_id == env_id:
            return task
    names = ", ".join(t.env_id for t in TASKS)
    declared = ", ".join(t.env_id for t in DECLARED_TASKS)
    if env_id in {t.env_id for t in DECLARED_TASKS}:
        raise ValueError(f"{env_id} is a declared vehicle's task ({declared}); this takes "
                         f"the 1/4-car's tasks: {names}")  # fmt: skip
    raise ValueError(f"task must be one of {names} (the declared vehicles' tasks, {declared}, "
                     f"have their own evaluation: evaluate.py --task), got {env_id!r}")  # fmt: skip


def register_tasks() -> None:
    """Register every task with Gymnasium (idempotent); its options are the registered
    kwargs, which ``gymnasium.make(id, **overrides)`` may still override."""
    from gymnasium.envs.registration import register, registry

    for task in TASKS:
        if task.env_id not in registry:
            register(id=task.env_id, entry_point=ENTRY_POINT,
                     vector_entry_point=VECTOR_ENTRY_POINT, kwargs=dict(task.kwargs))  # fmt: skip
    for task in DECLARED_TASKS:
        if task.env_id not in registry:
            register(id=task.env_id, entry_point=DECLARED_ENTRY_POINT,
                     vector_entry_point=DECLARED_VECTOR_ENTRY_POINT, kwargs=dict(task.kwargs))  # fmt: skip


def normalised_score(wk_m_s2: float, passive_m_s2: float, oracle_m_s2: float) -> float:
    """``(passive - x) / (passive - oracle)``: 0 for the passive damper, 1 for the oracle."""
    if not passive_m_s2 > oracle_m_s2:
        raise ValueError(f"passive_m_s2 must exceed oracle_m_s2, got {passive_m_s2} and "
                         f"{oracle_m_s2}")  # fmt: skip
    return (passive_m_s2 - wk_m_s2) / (passive_m_s2 - oracle_m_s2)


#: The lowest-Wk tuned law on each signal set and setting, for an env no task card decides
#: (``docs/figures/evaluation.json``, 10 episodes): on the full state the MPC (sim / hils 0.2490 /
#: 0.2388, the clipped LQR 0.2501 / 0.2396), with a preview the preview LQ (0.2379 / 0.2281); on
#: the measured signals the clipped LQR in sim (0.2502, the MPC 0.2513) and the MPC in hils
#: (0.2385, the LQR 0.2399), with a preview the preview MPC (0.2388 / 0.2273). ``sensors`` (a
#: subset of ``measured``: no gap, coil current or velocity estimates) has no law of its own:
#: the laws on measurable signals, as ``CapsuleSuspension-v0``'s card says.
_BEST_ON_SIGNALS = {
    ("full_state", False, "sim"): "mpc-biexp",
    ("full_state", False, "hils"): "mpc-biexp",
    ("full_state", True, "sim"): "preview-lq-biexp",
    ("full_state", True, "hils"): "preview-lq-biexp",
    ("measured", False, "sim"): "lqr-clipped-biexp-meas",
    ("measured", False, "hils"): "mpc-biexp-meas",
    ("measured", True, "sim"): "preview-mpc-biexp-meas",
    ("measured", True, "hils"): "preview-mpc-biexp-meas",
}
_ENV_DEFAULTS = {"setting": "sim", "observation": "sensors", "preview_points": 0}


def _signals(env_kwargs: dict[str, Any]) -> tuple[str, bool]:
    """What a policy on ``env_kwargs`` reads: ``full_state`` or measurable signals, and whether
    it has a preview of the guideway."""
    given = {**_ENV_DEFAULTS, **env_kwargs}
    full = given["observation"] == "full_state"
    return ("full_state" if full else "measured"), int(given["preview_points"] or 0) > 0


def reference_law_for(env_kwargs: dict[str, Any]) -> str:
    """The classical law to compare a policy trained on ``env_kwargs`` with, one that reads the
    same signals (the full state or measurable ones; a preview or none): the card's best law of
    the most specific task whose options ``env_kwargs`` has and whose policy reads those
    signals, else the lowest-Wk law on them in the env's setting (:data:`_BEST_ON_SIGNALS`).
    Never an ideal-sensor law for a policy on measured signals, nor one without the preview a
    policy has (issue 40: train.py compared every run with the ideal-sensor
    ``skyhook-cont-biexp``)."""
    given = {**_ENV_DEFAULTS, **env_kwargs}
    signals = _signals(given)
    same = lambda a, b: json.dumps(a) == json.dumps(b)  # noqa: E731 (a tuple is a JSON list)
    matching = [t for t in TASKS if t.kwargs and _signals(t.kwargs) == signals
                and all(same(given.get(k), v) for k, v in t.kwargs.items())]  # fmt: skip
    if matching:
        return max(matching, key=lambda t: len(t.kwargs)).best_classical
    setting = "hils" if given["setting"] == "hils" else "sim"
    return _BEST_ON_SIGNALS[(*signals, setting)]
