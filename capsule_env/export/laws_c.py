"""The classical laws a residual policy may ride on, as a few lines of C99 from their gains.

:func:`law_c` writes ``static float capsule_law(const float *obs)``: the law's action in
``[-1, 1]`` from the env's raw observation, computed as the Python law computes it (the signals
and the force in double precision, the action rounded to float32, then clipped), for the laws
whose action is a closed form of the current observation (no state, no solver):

==========================================  ===============================================
law (class)                                 action
==========================================  ===============================================
Skyhook, on-off (``skyhook-*``)             ``F = c_max v`` if ``z_c' v > 0`` else ``c_min v``
Skyhook, continuous (``skyhook-cont-*``)    ``F = c_sky z_c'`` if ``z_c' v > 0`` else 0
hybrid Skyhook-groundhook (``hybrid-*``)    ``alpha F_sky + (1 - alpha) F_ground``
clipped-optimal LQR (``lqr-clipped-*``)     ``F = -K x``, ``x = [stroke, z_c', gap, z_b']``
two-state Skyhook, ADD, SH-ADD (``-meas``)  ``i_on`` where the law is hard, else 0 A
==========================================  ===============================================

(force laws: ``a = F / max_force_n``; two-state laws, current mode: ``a = 2 i_on / i_max - 1``
or -1). The gain-scheduled LQR, the preview LQ law and the MPC are not written (a schedule,
a filter state, a QP solve per step): :func:`c_law_reason` says why, and the rig provides them.
"""

from __future__ import annotations

import math
from typing import Any

from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.controllers.classical import FACTORIES
from capsule_env.agents.controllers.law import SOURCES
from capsule_env.agents.controllers.lqr import STATE_SIGNALS, ClippedOptimalController
from capsule_env.agents.controllers.skyhook import HybridController, SkyhookController
from capsule_env.agents.controllers.two_state import (
    ADDController,
    MixedSkyhookADDController,
    SkyhookTwoStateController,
)
from capsule_env.engine.config import OBSERVATION_NAMES

__all__ = ["C_LAWS", "law_class", "c_law_reason", "law_c"]

#: The law classes written in C (exact classes: a subclass may act otherwise).
C_LAWS = (
    SkyhookController,
    HybridController,
    ClippedOptimalController,
    SkyhookTwoStateController,
    ADDController,
    MixedSkyhookADDController,
)


def law_class(name: str) -> type | None:
    """The class the registry's factory ``name`` builds (None for an unknown name)."""
    factory = FACTORIES.get(name)
    return getattr(factory, "func", factory) if factory is not None else None


def c_law_reason(name: str) -> str:
    """Why the law ``name`` has no C form (``""`` when it has one)."""
    cls = law_class(name)
    if cls is None:
        return f"{name!r} is not a classical controller"
    if cls not in C_LAWS:
        return (f"{name} ({cls.__name__}) keeps a state or solves a problem each step; its C "
                "form is not generated: the rig must provide it")  # fmt: skip
    return ""


def _g(value: Any) -> str:
    """A finite number as a C double literal (parenthesised when negative)."""
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"a law gain is {number}: it has no C form")
    return f"({number!r})" if number < 0 else repr(number)


def _signal(law: Any, name: str) -> str:
    """The C expression (double) of the physical signal ``name`` of the law."""
    columns = {col: k for k, col in enumerate(OBSERVATION_NAMES[law.observation])}
    cols = [columns[c] for c in SOURCES[law.observation][name]]
    if len(cols) == 1:
        return f"(double)obs[{cols[0]}]"
    return f"((double)obs[{cols[0]}] - (double)obs[{cols[1]}])"


def _force_body(law: Any) -> list[str]:
    """Lines computing ``double force_n`` of a force law."""
    s = {name: _signal(law, name) for name in law.SIGNALS}
    if isinstance(law, ClippedOptimalController):
        terms = [f"{_g(k)} * {s[name]}" for k, name in zip(law.gain, STATE_SIGNALS)]
        return ["double sum = 0.0;", *[f"sum += {t};" for t in terms], "force_n = -sum;"]
    body, rel = s["body_velocity"], s["relative_velocity"]
    lines = [f"const double body = {body};", f"const double rel = {rel};"]
    if isinstance(law, HybridController):
        bogie = s["bogie_velocity"]
        return [*lines, f"const double bogie = {bogie};",
                f"const double sky = (body * rel > 0.0) ? {_g(law.c_sky)} * body : 0.0;",
                f"const double ground = (-bogie * rel > 0.0) ? -{_g(law.c_ground)} * bogie : 0.0;",
                f"force_n = {_g(law.alpha)} * sky + (1.0 - {_g(law.alpha)}) * ground;"]  # fmt: skip
    if law.variant == "on_off":
        return [*lines, f"force_n = (body * rel > 0.0) ? {_g(law.c_max)} * rel : "
                f"{_g(law.c_min)} * rel;"]  # fmt: skip
    return [*lines, f"force_n = (body * rel > 0.0) ? {_g(law.c_sky)} * body : 0.0;"]


def _hard_body(law: Any) -> str:
    """The C condition (int) under which a two-state law is hard."""
    rel = _signal(law, "relative_velocity")
    if isinstance(law, SkyhookTwoStateController):
        return f"{_signal(law, 'body_velocity')} * {rel} > 0.0"
    acc = _signal(law, "body_acceleration")
    if isinstance(law, ADDController):
        return f"{acc} * {rel} > 0.0"
    vel, alpha = _signal(law, "body_velocity"), _g(law.alpha)
    return (f"({vel} * {vel} - {alpha} * {alpha} * {acc} * {acc} > 0.0) ? ({vel} * {rel} > "
            f"0.0) : ({acc} * {rel} > 0.0)")  # fmt: skip


def law_c(law: Controller) -> str:
    """C99 of ``static float capsule_law(const float *obs)`` for ``law`` (module docstring).
    ``ValueError`` for a law without a C form or with per-vehicle gains."""
    if type(law) not in C_LAWS:
        raise ValueError(c_law_reason(str(law.name)) or f"{law.name} has no C form")
    if any(isinstance(value, list) for value in law.gains().values()):
        raise ValueError(f"{law.name}: per-vehicle gains have no C form")
    if isinstance(law, (SkyhookTwoStateController, ADDController, MixedSkyhookADDController)):
        on = 2.0 * float(law.i_on) / law.max_current_a - 1.0
        body = [f"const float a = ({_hard_body(law)}) ? (float){_g(on)} : -1.0f;"]
    else:
        body = ["double force_n;", *_force_body(law),
                f"const float a = (float)(force_n / {_g(law.max_force_n)});"]  # fmt: skip
    body.append("return a > 1.0f ? 1.0f : (a < -1.0f ? -1.0f : a);")
    lines = [f"/* the base law {law.name} ({type(law).__name__}), gains {law.gains()} */",
             "static float capsule_law(const float *obs)", "{", *("    " + b for b in body), "}"]  # fmt: skip
    return "\n".join(lines) + "\n"
