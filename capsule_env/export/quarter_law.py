"""The contract's ``residual.base_law`` of a quarter-car residual policy.

A quarter-car residual rides on a law of the registry
(:data:`~capsule_env.agents.controllers.classical.FACTORIES`, built by ``make_controller(name)``
with its tuned gains). A law with a C form (:mod:`capsule_env.export.laws_c`) is in the exported
C file (``capsule_law``); the block says so and names it. A law without one (the semi-active
MPC of the shipped ``residual-ppo-mpc`` and ``residual-ppo-mpc-trip``, the gain-scheduled LQR,
the preview LQ law) is run by the rig, and the block carries what rebuilds it: every argument
of its class's constructor as plain JSON (the registry's options, the tuned weights the
factory reads from ``agents/controllers/tuned_gains.json``, each default made explicit) with
units, the plant and inverse-model parameters it is built from, the columns it reads (index and
name), the memories it keeps and whether the rig must solve a QP each control period.
"""

from __future__ import annotations

import dataclasses
import inspect
from typing import Any

import numpy as np

__all__ = ["quarter_car_block", "law_arguments"]

#: Units of the constructor arguments of the quarter-car laws without a C form.
UNITS = {
    "inverse_model": "the inverse model's name (the damper band the law plans in; the env's "
                     "inverse on the rig)",
    "q_stroke": "1/s^4", "q_levitation": "1/s^4", "r_force": "1/kg^2",
    "vehicle": "null: the default quarter-car (VehicleParams()), whose values "
               "vehicle_parameters records",
    "max_force_n": "N (the action's force scale)", "observation": "the observation set's name",
    "preview": "true/false: the guideway preview", "preview_points": "points",
    "preview_horizon_s": "s", "horizon_steps": "control periods",
    "move_blocks": "control periods each (null: one move per period)",
    "delay_steps": "control periods", "coil_time_constant_s": "s", "dt_s": "s",
    "solver": "the QP solver's options (SolverOptions; eps_* on forces scaled by max_force_n, "
              "time_limit_s in s, secant_m_s in m/s)",
    "wk_cost": "true/false: the cost's car-body acceleration ISO 2631-1 Wk-weighted",
    "levitation": "the levitation model's name",
    "levitation_params": "EdsParams fields (units in their names)",
    "top_speed_kmh": "km/h", "grid_step_kmh": "km/h",
}  # fmt: skip
#: What each class without a C form keeps from step to step (``episode_start`` restarts it).
_STATE = {
    "MPCController": "per vehicle: its own requests in flight (delay_steps of them: the force "
                     "the inverse model makes of the law's own request at the measured stroke "
                     "and rate, not of the combined action), the previous plan's predicted "
                     "stroke rates and strokes (the next step's sign pattern and band-edge "
                     "linearisation points), DAQP's warm start (its previous solution) and, "
                     "with wk_cost, the Wk filter's state. At an episode's first step "
                     "(episode_start) the vehicle starts as under a fresh law: the requests in "
                     "flight and the Wk state zeroed, no previous plan (predicted rates and "
                     "strokes 0) and no warm start (the solver set up afresh). The acting "
                     "force is estimated each step from the coil_current_a column through the "
                     "inverse model",
    "PreviewLQController": "per vehicle: its own requests in flight (delay_steps of them, "
                           "zeroed at each episode's first step)",
    "ScheduledLQRController": "none (the gain is looked up at the measured speed each step)",
}  # fmt: skip


def _plain(value: Any) -> Any:
    """``value`` as plain JSON values: arrays and tuples as lists, numpy scalars as floats."""
    if isinstance(value, np.ndarray):
        return value.item() if value.ndim == 0 else value.tolist()
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return value


def law_arguments(name: str, law: Any) -> dict[str, Any]:
    """Every constructor argument of the registry's law ``name`` (``law``, as
    ``make_controller(name)`` built it) as plain JSON values: the factory's own options, the
    gains the law took (the tuned ones), the rest at the class's defaults, the dict-valued
    options (the QP solver's, the levitation's) written out; ``cls(**arguments)`` rebuilds it."""
    from capsule_env.agents.controllers.classical import FACTORIES

    factory = FACTORIES[name]
    cls = getattr(factory, "func", factory)
    bound = inspect.signature(cls).bind_partial(*getattr(factory, "args", ()),
                                                **getattr(factory, "keywords", {}))  # fmt: skip
    for param in inspect.signature(cls).parameters:
        try:
            law.gain_key(param)
        except KeyError:
            continue
        bound.arguments[param] = getattr(law, param)
    bound.apply_defaults()
    out = dict(bound.arguments)
    if "solver" in out:
        out["solver"] = dataclasses.asdict(law.solver_options)
    if "levitation_params" in out and out["levitation_params"] is None:
        from capsule_env.envelope.levitation import EdsParams

        out["levitation_params"] = dataclasses.asdict(EdsParams())
    if out.get("vehicle") is not None:
        raise ValueError(f"{name}: its factory gives a vehicle; the contract records only the "
                         "default one")  # fmt: skip
    return {k: _plain(v) for k, v in out.items()}


def _reads(law: Any, names: tuple[str, ...]) -> dict[str, Any]:
    read = list(law.signals_read)
    return {"columns": [{"index": names.index(c), "name": c} for c in read if c in names],
            "note": "the raw observation (not normalised), in the contract's order and units"}  # fmt: skip


def _plant(law: Any) -> dict[str, Any]:
    """The vehicle's and the inverse model's parameters the law is built from."""
    from capsule_env.export.base_law import inverse_model_record
    from capsule_env.vehicles import VehicleParams

    out: dict[str, Any] = {
        "vehicle_parameters": dataclasses.asdict(VehicleParams()),
        "vehicle_parameters_note": "the law's model is this nominal quarter-car (the "
                                   "constructor's vehicle null), whatever the task's plant "
                                   "(levitation, payload) is",
    }  # fmt: skip
    if hasattr(law, "damper"):
        out["inverse_model"] = inverse_model_record(law.damper)
    return out


def _no_c_block(name: str, law: Any, names: tuple[str, ...]) -> dict[str, Any]:
    from capsule_env.agents.controllers.mpc import MPCController

    arguments = law_arguments(name, law)
    qp = isinstance(law, MPCController)
    doc = type(law).__module__
    return {
        "constructor": arguments, "units": {k: UNITS[k] for k in arguments},
        "weights_tuned": bool(getattr(law, "gains_tuned", False)),
        "weights_from": f"agents/controllers/tuned_gains.json, the entry {name} (else its linear "
                        "twin's): what make_controller(name) reads; the constructor holds them",
        **_plant(law), "reads": _reads(law, names),
        "state": _STATE.get(type(law).__name__, "see the class's docstring"),
        "nonfinite": "a vehicle whose read columns hold a NaN or inf: the MPC requests 0 N that "
                     "step; the sample does not enter its Wk filter and the next plan starts afresh; with a "
                     "delay, the record of requests in flight holds what the damper makes of 0 N "
                     "at the sample with its non-finite entries read as 0" if qp else
                     "no special handling: the law computes with the values as given",
        "rig_solves_qp": qp,
        "rebuild": f"Python: {type(law).__name__}(**constructor)"
                   + (" (its QP solver, DAQP: the mpc extra)" if qp else "")
                   + f"; elsewhere: the law {doc}'s docstring describes, at these values; the "
                     "exported C file does not contain it",
    }  # fmt: skip


def quarter_car_block(name: str, scale: float, names: tuple[str, ...]) -> dict[str, Any]:
    """The ``base_law`` block of a quarter-car residual on the registry's law ``name`` (scale
    ``scale``, observation columns ``names``)."""
    from capsule_env.agents.controllers.classical import make_controller
    from capsule_env.export.base_law import class_path, combine_rule
    from capsule_env.export.laws_c import c_law_reason

    law = make_controller(name)
    slots = ["secondary_damper"]
    block = {"name": law.name, "class": class_path(law), "vehicle": "quarter_car",
             "slots": slots, "combine": combine_rule(scale, slots)}  # fmt: skip
    if not c_law_reason(name):
        return block | {
            "in_c_file": True, "constructor": None, "rig_solves_qp": False,
            "rebuild": "the exported C file's capsule_law(obs) is this law at residual.law_gains; "
                       "capsule_control(obs, action) is the law and the residual combined",
        }  # fmt: skip
    return block | {"in_c_file": False} | _no_c_block(name, law, names)
