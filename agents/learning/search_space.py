"""The gains of each tuned classical law and the ranges the search explores.

Every feedback law of :mod:`capsule_env.agents.controllers.classical` except the paper-reproduction on-off Skyhooks
(:data:`capsule_env.agents.controllers.classical.PAPER_FIXED`) has a :class:`SearchSpace` here: its free gains (the
constructor's names), each on a log or linear range, the gains tied to another (the hybrid
law's ``c_ground = c_sky``) and the gain swept for the Pareto figure
(``experiments/pareto.py``). Ranges are wide on purpose (one to six decades): the search, not
the range, picks the value. A law made for another task than the env's defaults names it
(:attr:`SearchSpace.task`, a registered id of :mod:`capsule_env.tasks`): its search runs with
that task's env options, on the same training bank, and may set its own stroke limit
(:attr:`SearchSpace.stroke_limit_m`, recorded in its entry of the gains file).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Param:
    """One free gain: constructor name, range and scale (log: uniform in log10)."""

    name: str
    low: float
    high: float
    log: bool = True

    def to_value(self, u: np.ndarray) -> np.ndarray:
        """Unit coordinate ``u`` in [0, 1] -> the gain."""
        u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
        if self.log:
            value = 10.0 ** (np.log10(self.low) + u * (np.log10(self.high) - np.log10(self.low)))
        else:
            value = self.low + u * (self.high - self.low)
        return np.clip(value, self.low, self.high)  # no rounding past an end

    def to_unit(self, value: np.ndarray) -> np.ndarray:
        """The gain -> its unit coordinate."""
        value = np.asarray(value, dtype=float)
        if self.log:
            span = np.log10(self.high) - np.log10(self.low)
            return (np.log10(value) - np.log10(self.low)) / span
        return (value - self.low) / (self.high - self.low)


@dataclass(frozen=True)
class SearchSpace:
    """The free gains of one controller, the tied ones and the one swept for the figure."""

    params: tuple[Param, ...]
    tied: dict[str, str] = field(default_factory=dict)  # gain -> the free gain it equals
    sweep: str = ""  # the gain varied along the Pareto curve (default: the first)
    task: str = ""  # the registered task whose env options the search runs in ("": defaults)
    stroke_limit_m: float = 0.0  # the task's stroke limit (0: the search settings' 15 mm)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def sweep_param(self) -> Param:
        name = self.sweep or self.params[0].name
        return next(p for p in self.params if p.name == name)

    def gains(self, units: np.ndarray) -> dict[str, np.ndarray]:
        """Candidates in unit coordinates ``(C, d)`` -> constructor keyword arguments, each
        ``(C,)`` (tied gains included)."""
        units = np.atleast_2d(units)
        out = {p.name: p.to_value(units[:, k]) for k, p in enumerate(self.params)}
        out.update({gain: out[source] for gain, source in self.tied.items()})
        return out

    def coarse_grid(self, points: int) -> np.ndarray:
        """The full grid of ``points`` per gain over the ranges, unit coordinates ``(C, d)``."""
        axis = np.linspace(0.0, 1.0, points)
        return np.array(list(itertools.product(axis, repeat=len(self.params))))

    def local_grid(self, center: np.ndarray, step: float, half_width: int = 2) -> np.ndarray:
        """The grid ``center + j step`` (``j = -half_width .. half_width`` per gain) clipped to
        the ranges, without repeats, unit coordinates."""
        offsets = step * np.arange(-half_width, half_width + 1)
        axes = [np.clip(c + offsets, 0.0, 1.0) for c in center]
        grid = np.array(list(itertools.product(*axes)))
        return np.unique(np.round(grid, 12), axis=0)


_C = Param("c_sky", 1.0e3, 3.0e5)  # N s/m
_I_ON = Param("i_on", 0.02, 1.5)  # A (the damper's i_max is 1.5 A)
_ALPHA = Param("alpha", 0.0, 1.0, log=False)  # hybrid blend
_HYBRID = SearchSpace((_ALPHA, _C), tied={"c_ground": "c_sky"}, sweep="c_sky")
_LQR = SearchSpace(
    (
        Param("q_stroke", 1.0e-2, 1.0e6),  # 1/s^4
        Param("q_levitation", 1.0e-2, 1.0e6),  # 1/s^4
        Param("r_force", 1.0e-12, 1.0e-6),  # 1/kg^2
    ),
    sweep="r_force",
)
#: The MPC: only ``r_force`` is searched (a modest budget: a plan per vehicle per step costs
#: about a millisecond), the state weights kept at the linear twin's tuned values
#: (``capsule_env.agents.controllers.mpc.LINEAR_TWIN``), over two decades either side of them.
_MPC = SearchSpace((Param("r_force", 1.0e-10, 1.0e-6),))

#: The search space of every tuned controller, by name.
SEARCH_SPACES: dict[str, SearchSpace] = {
    # ideal sensors (full_state)
    "skyhook-cont-biexp": SearchSpace((_C,)),
    "skyhook-cont-csdc": SearchSpace((_C,)),
    "skyhook-cont-tanh": SearchSpace((_C,)),
    "hybrid-biexp": _HYBRID,
    "lqr-clipped-biexp": _LQR,
    # measured
    "skyhook-meas": SearchSpace((_I_ON,)),
    "skyhook-cont-biexp-meas": SearchSpace((_C,)),
    "hybrid-biexp-meas": _HYBRID,
    "add-meas": SearchSpace((_I_ON,)),
    # alpha: the crossing frequency 1 / (2 pi alpha) from 0.32 Hz to 32 Hz
    "sh-add-meas": SearchSpace((_I_ON, Param("alpha", 0.005, 0.5)), sweep="i_on"),
    "lqr-clipped-biexp-meas": _LQR,
    # guideway preview
    "preview-lq-biexp": _LQR,
    "preview-lq-biexp-meas": _LQR,
    "mpc-biexp-meas": _MPC,
    "preview-mpc-biexp-meas": _MPC,
    "mpc-biexp": _MPC,
    "preview-mpc-biexp": _MPC,
    # speed-dependent plant: the gain-scheduled LQR, searched on the trip task
    # On the trip the tube's sag and pylon steps drive strokes no law keeps under 15 mm (passive:
    # 18.5 mm on the training episodes, the fixed LQR 19.4 mm): half the 60 mm bump stop.
    "lqr-sched-biexp-meas": SearchSpace(
        _LQR.params, sweep="r_force", task="CapsuleTrip-v0", stroke_limit_m=0.030
    ),
}
