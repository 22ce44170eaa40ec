"""The contract's ``residual.base_law``: what a rig needs to rebuild a residual policy's law.

A residual policy's artifacts compute the residual alone. A quarter-car residual's law is the
registry's (:mod:`capsule_env.export.quarter_law`: in the C file when it has a C form, else
rebuilt from its constructor's arguments, the semi-active MPC's among them). On a declared
vehicle (the half-car) the law it rides on
(:data:`~capsule_env.agents.learning.sb3_policy.DECLARED_LAWS`) has no C form, so the rig runs
it. The block says what that law is: its name and class, every
constructor argument as plain JSON values (the law's ``arguments``: ``cls(**constructor)``
rebuilds it, the tuned weights included) with their units, the vehicle's and the inverse
model's parameters it was built from, the observation columns it reads, the memories it keeps,
how each damper slot's action combines with the residual, and whether the rig must solve a QP
each control period (the MPC: yes; the per-bogie LQR: no, its gain and formula are here).
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any

from capsule_env.export.source import PolicySource

__all__ = [
    "base_law",
    "declared_residual_law",
    "rebuild_base_law",
    "class_path",
    "combine_rule",
    "inverse_model_record",
]

#: Units of the half-car MPC's constructor arguments.
_MPC_UNITS = {"q_stroke": "1/s^4", "q_levitation": "1/s^4", "r_force": "1/kg^2",
              "preview": "true/false: the wheelbase preview", "horizon_steps": "control periods",
              "delay_steps": "control periods", "move_blocks": "control periods each (null: "
              "one move per period)", "coil_time_constant_s": "s", "dt_s": "s",
              "speed_kmh": "km/h", "max_force_n": "N",
              "solver": "the QP solver's options (SolverOptions; eps_* on forces scaled by "
                        "max_force_n, time_limit_s in s, secant_m_s in m/s)"}  # fmt: skip
#: Units of a Bi-exponential damper's parameters, by the end of their names (first match).
_DAMPER_UNITS = (("_a0", "N"), ("_a1", "N/A"), ("_b0", "N s/m"), ("_b1", "N s/(m A)"),
                 ("_c0", "N"), ("_c1", "N/A"), ("_d", "s/m"), ("_a", "A"), ("_s", "s"),
                 ("_m", "m"))  # fmt: skip
#: Units of the per-bogie LQR's gain entries (on x_s's entries, in order).
_GAIN_UNITS = ["N/m", "N s/m", "N/m", "N s/m"]


def declared_residual_law(name: str, vehicle: str, path: Any) -> Any:
    """The law ``name`` a residual policy (its file ``path``) of the declared vehicle
    ``vehicle`` rides on, built as its loader builds it
    (:func:`~capsule_env.agents.learning.sb3_policy.declared_law`) but without needing the QP
    solver (the MPC sets its solver up at its first step). ``ValueError`` for a law of another
    vehicle."""
    from capsule_env.agents.learning.sb3_policy import declared_law
    from capsule_env.evaluation.half_car import TUNED_MPC, tuned_mpc

    if name not in TUNED_MPC:
        return declared_law(name, vehicle, path)
    if vehicle != "half_car":
        raise ValueError(f"{path}: its residual law {name} is the half_car's; its vehicle is "
                         f"{vehicle!r}")  # fmt: skip
    return tuned_mpc(name)


def class_path(law: Any) -> str:
    """The law's class as its public import path (``capsule_env.agents...``)."""
    return f"{type(law).__module__}.{type(law).__qualname__}"


def _slots(vehicle: str) -> list[str]:
    from capsule_env.vehicles import model_named

    return [d.name for d in model_named(vehicle).dampers]


def combine_rule(scale: float, slots: list[str]) -> str:
    """The combination of the law's and the residual's action, per damper slot, in words."""
    order = ", ".join(f"{k} {s}" for k, s in enumerate(slots))
    return (f"per damper slot s ({order}; the action's index): action[s] = clip(law_action[s] "
            f"+ {scale:g} * residual[s], -1, 1) in double precision, then float32 (the C "
            "file's capsule_combine, called once per slot); law_action[s] = the law's force "
            "request for slot s / max_force_n, rounded to float32, then clipped to [-1, 1]; "
            "where a vehicle's observation has a non-finite value (NaN, inf) its residual is 0 "
            "on every slot (the law alone): the Python policy, the C file's capsule_policy "
            "and the ONNX graph alike")  # fmt: skip


def inverse_model_record(damper: Any) -> dict[str, Any]:
    """A Bi-exponential inverse model's name, parameters and their units."""
    parameters = dataclasses.asdict(damper)
    return {"name": damper.name, "parameters": parameters,
            "units": {p: next(u for end, u in _DAMPER_UNITS if p.endswith(end))
                      for p in parameters}}  # fmt: skip


def _mpc_block(law: Any, names: tuple[str, ...], slots: list[str]) -> dict[str, Any]:
    from capsule_env.vehicles import model_named

    vehicle = str(law.env_kwargs["vehicle"])
    damper = law.damper
    read = [{"index": k, "name": n} for k, n in enumerate(names)
            if n.startswith(tuple(f"{s}_" for s in slots))]  # fmt: skip
    return {
        "units": _MPC_UNITS,
        "weights_tuned": bool(getattr(law, "gains_tuned", False)),
        "weights_from": "capsule_env.evaluation.half_car.TUNED_MPC (tuned on the training bank, "
                        "guideway seed 0, episodes 0..9; docs/half-car.md)",
        "vehicle_parameters": dataclasses.asdict(model_named(vehicle).params()),
        "vehicle_parameters_note": "the prediction model is the vehicle's relative form at these "
                                   "values (units in the names), not an argument: the class "
                                   "builds it from the registered vehicle",
        "inverse_model": inverse_model_record(damper),
        "reads": {"columns": read, "note": "the raw observation (not "
                  "normalised), in the contract's order and units"},  # fmt: skip
        "state": "per vehicle, restarted at each episode's first step (episode_start) as "
                 "under a fresh law (the last step's sample from the episode's first "
                 "observation, the rest zero, no plan, the solver set up afresh): the "
                 "front gap and lower velocity estimate of the last step (the rise estimate), "
                 "the wheelbase window of rises, its own requests in flight (what the damper "
                 "makes of the law's own request, not of the combined action), the coil "
                 "currents' estimate (from the last_current_command_a columns through the "
                 "coil lag), the previous plan (the QP's reference and warm start)",
        "nonfinite": "a vehicle whose 16 measured columns hold a NaN or inf (any of them): the "
                     "MPC requests 0 N on both slots that step and its next plan starts "
                     "afresh; the non-finite values enter its memories (the rise window, the "
                     "coil currents' estimate) as zeros",
        "rig_solves_qp": True,
        "rebuild": "Python: HalfCarMPC(**constructor) (its QP solver, DAQP: the mpc extra); "
                   "elsewhere: set up and solve, each control period, the QP that "
                   "capsule_env.agents.controllers.half_car_mpc's docstring describes, from "
                   "these values; the exported C file does not contain it",
    }  # fmt: skip


def _lqr_block(law: Any, names: tuple[str, ...]) -> dict[str, Any]:
    per, offsets = law.slot_columns, law.state_offsets
    columns = [[{"index": s * per + o, "name": names[s * per + o]} for o in offsets]
               for s in range(len(names) // per)]  # fmt: skip
    return {
        "units": {"vehicle": "a registered vehicle's name", "max_force_n": "N"},
        "gain_per_slot": [float(g) for g in law.gain], "gain_units": _GAIN_UNITS,
        "gain_from": "the 1/4-car's tuned lqr-clipped-biexp-meas (the same gain on each slot)",
        "formula": "per slot s: x_s = the observation's values at state_columns[s]; force "
                   "F_s = -(gain_per_slot . x_s) N; law_action[s] = clip(F_s / max_force_n, "
                   "-1, 1)",
        "state_columns": columns,
        "reads": {"note": "the raw observation (not normalised), in the contract's order "
                          "and units"},
        "state": "none (a static law)",
        "nonfinite": "no special handling: the formula computes with the values as given (a NaN "
                     "in a slot's state_columns gives that slot a NaN law_action, an inf one "
                     "F_s = +-inf, clipped to -1 or 1, or NaN where infinities cancel; the "
                     "other columns are not read)",
        "rig_solves_qp": False,
        "rebuild": "Python: IndependentClippedLQR(**constructor); elsewhere: the formula",
    }  # fmt: skip


def base_law(source: PolicySource, kwargs: dict[str, Any],
             names: tuple[str, ...]) -> dict[str, Any] | None:  # fmt: skip
    """The ``base_law`` block (module doc) of ``source`` trained with the env options
    ``kwargs`` (observation columns ``names``); None unless a residual policy."""
    from capsule_env.agents.controllers.half_car_mpc import HalfCarMPC
    from capsule_env.export.quarter_law import quarter_car_block

    vehicle, res = str(kwargs.get("vehicle", "quarter_car")), source.residual
    if res is None:
        return None
    if vehicle == "quarter_car":
        return quarter_car_block(res.law_name, res.scale, names)
    law = declared_residual_law(res.law_name, vehicle, source.zip_path)
    slots = _slots(vehicle)
    block = {"name": law.name, "class": class_path(law), "constructor": dict(law.arguments),
             "vehicle": vehicle, "slots": slots, "combine": combine_rule(res.scale, slots),
             "in_c_file": False}  # fmt: skip
    if isinstance(law, HalfCarMPC):
        return block | _mpc_block(law, names, slots)
    return block | _lqr_block(law, names)


def _read_by_class(law: Any, block: dict[str, Any]) -> dict[str, tuple[Any, Any]]:
    """What the law's class reads from this installation rather than takes as an argument:
    ``(this installation's, the block's)`` by the block's entry that records it (those the
    block has)."""
    from capsule_env.vehicles import model_named

    vehicle = model_named(block["vehicle"])
    here = {
        "vehicle_parameters": lambda: dataclasses.asdict(vehicle.params()),
        "inverse_model.name": lambda: law.damper.name,
        "inverse_model.parameters": lambda: dataclasses.asdict(law.damper),
        "gain_per_slot": lambda: [float(g) for g in law.gain],
    }
    out = {}
    for key, value in here.items():
        outer, _, inner = key.partition(".")
        if outer not in block:
            continue
        if inner and not isinstance(block[outer], dict):
            raise ValueError(f"base_law.{outer} must be a JSON object (its {inner} is checked "
                             f"against this installation's), got {block[outer]!r:.80}")  # fmt: skip
        if not inner or inner in block[outer]:
            out[key] = (value(), block[outer][inner] if inner else block[outer])
    return out


def _differences(here: Any, given: Any, key: str) -> list[str]:
    """The entries (``key.name``) where ``given`` differs from ``here``."""
    if isinstance(here, dict) and isinstance(given, dict):
        return [d for k in sorted(set(here) | set(given))
                for d in _differences(here.get(k), given.get(k), f"{key}.{k}")]  # fmt: skip
    return [] if here == given else [key]


def rebuild_base_law(block: dict[str, Any]) -> Any:
    """The law a contract's ``residual.base_law`` ``block`` describes, built through its
    class's constructor from ``constructor``. ``ValueError`` naming the entry when the law is
    in the C file (``in_c_file``), the block names no class of
    ``capsule_env.agents.controllers``, has no ``constructor`` object or
    ``vehicle`` name, or when what the class reads from this installation rather than takes
    (the vehicle's and the inverse model's parameters, the per-bogie LQR's gain) differs from
    the block's record of it; the constructor's own ``ValueError`` for a bad argument."""
    if not isinstance(block, dict):
        raise ValueError(f"base_law must be a JSON object, got {type(block).__name__}")
    if block.get("in_c_file") is True:
        raise ValueError(f"base_law.in_c_file is true: the law {block.get('name')} is the "
                         "exported C file's capsule_law (capsule_control: the law and the "
                         "residual combined); there is no constructor to rebuild it from")  # fmt: skip
    path = block.get("class")
    module, _, name = str(path).rpartition(".")
    cls = None
    if module.startswith("capsule_env.agents.controllers."):  # nothing else is imported
        try:
            cls = getattr(importlib.import_module(module), name, None)
        except ImportError:
            cls = None
    if not isinstance(cls, type):
        raise ValueError(f"base_law.class must be a class of capsule_env.agents.controllers, "
                         f"got {path!r}")  # fmt: skip
    if not isinstance(block.get("constructor"), dict) or not isinstance(block.get("vehicle"), str):
        raise ValueError("base_law must hold a constructor object and a vehicle name")
    law = cls(**block["constructor"])
    changed = [d for key, (here, given) in _read_by_class(law, block).items()
               for d in _differences(here, given, f"base_law.{key}")]  # fmt: skip
    if changed:
        raise ValueError(f"{', '.join(changed)}: the contract's value differs from this "
                         f"installation's, which {name} is built from")  # fmt: skip
    return law
