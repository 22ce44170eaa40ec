"""The tube on its pylons: the static sag of every span and the pylons' settlement.

A Hyperloop tube is an elevated beam on pylons. Under its own weight each span sags between its
supports, and pylons settle by different amounts; both are deterministic along the line and add
to the random irregularity of :mod:`capsule_env.guideway.random`. At 810 km/h a 30 m span passes
7.5 times a second: the sag excites about 7.5 Hz and its harmonics, above the bogie mode.

Shapes (``xi = x / L`` within a span of length ``L``, ``delta`` the sag at mid-span, elevation
negative downwards):

- ``continuous`` (default): an interior span of a long continuous beam under a uniform load,
  ``w = -16 delta xi^2 (1 - xi)^2`` (the clamped-clamped beam's deflection: zero slope over each
  pylon, so the line has no kinks);
- ``simply_supported``: a chain of simple spans, ``w = -(16/5) delta (xi - 2 xi^3 + xi^4)``
  (Euler-Bernoulli beam under a uniform load, ``5 q L^4 / 384 EI`` at mid-span), with a kink of
  slope ``16 delta / (5 L)`` on each side of every pylon.

Pylon settlement: each pylon sits ``N(0, sigma)`` away from the line, drawn from the given seed;
the tube follows the offsets linearly between pylons (a rigid-body tilt of each span).

Defaults, [reconstructed], every one overridable (:class:`SpanParams`): spans of 30 m (the
pylon spacing of the Hyperloop Alpha design, SpaceX 2013: "pylons ... every 100 ft (30 m)");
a mid-span sag of ``L / 3000`` (10 mm at 30 m: the order of the passenger-comfort limit on
the vertical deflection of high-speed railway bridges of that span, EN 1990 Annex A2, A2.4.4.3;
a tube that meets it under its own weight is a conservative case, a precambered one sags less);
pylon settlement 1 mm standard deviation.

Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capsule_env.common.validation import check_choice, check_in_range

__all__ = ["SPAN_SHAPES", "SpanParams", "span_shape", "span_profile"]

#: Deflection shapes of :class:`SpanParams`.
SPAN_SHAPES = ("continuous", "simply_supported")


@dataclass(frozen=True)
class SpanParams:
    """The tube's spans (see the module docstring for the sources).

    Attributes
    ----------
    span_m : pylon spacing (m), default 30.
    sag_m : static sag at mid-span (m), default ``span_m / 3000`` when None.
    shape : ``"continuous"`` or ``"simply_supported"``.
    pylon_offset_std_m : standard deviation of the pylons' settlement (m), default 1e-3.
    """

    span_m: float = 30.0
    sag_m: float | None = None
    shape: str = "continuous"
    pylon_offset_std_m: float = 1e-3

    def __post_init__(self) -> None:
        check_in_range("span_m", self.span_m, 1.0, 1000.0)
        if self.sag_m is not None:
            check_in_range("sag_m", self.sag_m, 0.0, 0.1)
        check_choice("shape", self.shape, SPAN_SHAPES)
        check_in_range("pylon_offset_std_m", self.pylon_offset_std_m, 0.0, 0.05)

    @property
    def mid_span_sag_m(self) -> float:
        """The sag at mid-span actually used (m)."""
        return self.span_m / 3000.0 if self.sag_m is None else float(self.sag_m)


def span_shape(xi: np.ndarray, shape: str) -> np.ndarray:
    """The unit deflection (1 at mid-span, positive downwards) at ``xi = x / L`` in ``[0, 1]``."""
    check_choice("shape", shape, SPAN_SHAPES)
    if shape == "continuous":
        return 16.0 * xi * xi * (1.0 - xi) ** 2
    return 3.2 * (xi - 2.0 * xi**3 + xi**4)


def span_profile(
    length_m: float, spacing_m: float, params: SpanParams | None = None, seed: int | None = 0
) -> np.ndarray:
    """The spans' elevation (m, negative downwards) at ``x_j = j * spacing_m``, ``0 <= x_j <=
    length_m``: the sag of every span plus the pylons' settlement (drawn from ``seed``; the first
    pylon stands at x = 0)."""
    params = params or SpanParams()
    check_in_range("length_m", length_m, 0.0, 1e8)
    check_in_range("spacing_m", spacing_m, 1e-4, 1e3)
    x = np.arange(int(np.floor(length_m / spacing_m + 1e-9)) + 1) * spacing_m
    span_index = np.floor(x / params.span_m)
    xi = x / params.span_m - span_index
    sag = -params.mid_span_sag_m * span_shape(xi, params.shape)
    n_pylons = int(span_index[-1]) + 2
    offsets = np.random.default_rng(seed).normal(0.0, params.pylon_offset_std_m, n_pylons)
    pylons = np.arange(n_pylons) * params.span_m
    return sag + np.interp(x, pylons, offsets)
