"""A vehicle as data: its bodies' coordinates, its points, its springs, dashpots and damper slots,
and the guideway contacts it stands on (docs/model.md, section 2).

A :class:`VehicleModel` declares, once, everything the plant, the env and the controllers read
about a vehicle:

- its **coordinates** (generalised displacements, each with its unit and the parameter that is
  its mass or inertia: the mass matrix is diagonal in them);
- its **points**: the vertical displacement of a point of a body is a linear combination of the
  coordinates (``z + x theta`` for a point ``x`` ahead of a pitching body's centre);
- its **contacts**: the points where the guideway acts, each at a longitudinal offset (m, > 0
  ahead of the reference point), so that a contact's guideway input is the profile at its own
  position (a rear bogie meets what the front one met ``offset / speed`` earlier);
- its **elements**, in order: springs and dashpots between two points (or a point and a
  contact), and the damper slots where a semi-active damper acts (one action per slot).

The **equations of motion** follow from the elements and nothing else::

    M q'' = - sum_e J_e^T f_e,   f_e = k_e d_e   (spring),   c_e d_e'   (dashpot),   F_s   (slot)

with ``d_e = J_e q - g_e z_g`` the element's deflection (its upper point's displacement less
its lower point's, the guideway's elevation where the lower end is a contact) and ``F_s`` the
damper force, positive when it resists a positive stroke rate. The declaration is plain numbers
and names: an array backend (numba today, JAX for GPUs) compiles the same sums
(:mod:`capsule_env.vehicles.linear` derives the linear model every controller reads from it).

Every element coefficient and every mass names a field of the vehicle's parameter dataclass
(``params``), which carries the documented defaults, their provenance and their accepted ranges.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from capsule_env.common.validation import check_real

__all__ = [
    "Coordinate",
    "Point",
    "Contact",
    "Element",
    "SPRING",
    "DASHPOT",
    "DAMPER",
    "VehicleModel",
]

#: Element kinds.
SPRING, DASHPOT, DAMPER = "spring", "dashpot", "damper"
#: Units of a coordinate: a displacement or an angle.
UNITS = ("m", "rad")


@dataclass(frozen=True)
class Coordinate:
    """A generalised coordinate: ``name`` (with its unit, e.g. ``car_body_displacement_m``),
    ``unit`` (``"m"`` or ``"rad"``), ``inertia``: the parameter holding its mass (kg) or
    moment of inertia (kg m^2), and ``rate_name``: its velocity's name with unit."""

    name: str
    unit: str
    inertia: str
    rate_name: str

    def __post_init__(self) -> None:
        _need_strings(self, "name", "unit", "inertia", "rate_name")


@dataclass(frozen=True)
class Point:
    """A point on the vehicle: ``name`` and its displacement ``sum(coefficient * coordinate)``
    as ``((coordinate name, coefficient), ...)``; a coefficient is a number or the name of a
    length parameter (a lever arm, m)."""

    name: str
    terms: tuple[tuple[str, float | str], ...]

    def __post_init__(self) -> None:
        _need_strings(self, "name")
        terms = self.terms
        if isinstance(terms, (tuple, list)) and all(
            isinstance(t, (tuple, list)) and len(t) == 2 for t in terms
        ):
            object.__setattr__(self, "terms", tuple(tuple(t) for t in terms))
        else:
            raise TypeError(f"point {self.name!r} terms must be (coordinate, coefficient) pairs, "
                            f"e.g. (('car_body_displacement_m', 1.0),), got {terms!r}")  # fmt: skip
        for coordinate, coefficient in self.terms:
            if not isinstance(coordinate, str):
                raise TypeError(f"point {self.name!r} names coordinates by their names "
                                f"(strings), got {coordinate!r}")  # fmt: skip
            _geometry_number(coefficient, f"point {self.name!r} coefficient of {coordinate!r}")


@dataclass(frozen=True)
class Contact:
    """Where the guideway acts: ``name`` and its longitudinal offset (m, > 0 ahead of the
    vehicle's reference point; a number or the name of a length parameter). Its input is the
    guideway's elevation at its own position."""

    name: str
    offset_m: float | str = 0.0

    def __post_init__(self) -> None:
        _need_strings(self, "name")
        _geometry_number(self.offset_m, f"contact {self.name!r} offset_m")


@dataclass(frozen=True)
class Element:
    """A spring, a dashpot or a damper slot between ``upper`` (a point) and ``lower`` (a point
    or a contact). ``coefficient``: the parameter of its stiffness (N/m) or damping (N s/m);
    ``None`` for a damper slot. ``passive``: for a damper slot, the parameter naming the
    linear damper of its passive baseline (N s/m), if any: a record for the linear analyses,
    which take it as their ``slot_damping`` argument when given it; nothing reads it on its
    own. The env's ``damper="passive"`` is the ``LinearDamper`` of ``damper_params`` in every
    slot (docs/model.md, section 2), whatever this parameter's value."""

    kind: str
    name: str
    upper: str
    lower: str
    coefficient: str | None = None
    passive: str | None = None

    def __post_init__(self) -> None:
        _need_strings(self, "kind", "name", "upper", "lower")


@dataclass(frozen=True)
class VehicleModel:
    """One vehicle, declared (module doc). ``params``: its parameter dataclass (frozen, with
    defaults); ``comfort_points``: the points whose acceleration the ride metric weighs
    (one for the 1/4-car: the car body); ``relative_positions``: the springs whose deflections
    are the position states of the controllers' relative form (one per coordinate, in
    coordinate order; :func:`capsule_env.vehicles.linear.relative_model`)."""

    name: str
    params: type
    coordinates: tuple[Coordinate, ...]
    points: tuple[Point, ...]
    contacts: tuple[Contact, ...]
    elements: tuple[Element, ...]
    comfort_points: tuple[str, ...]
    relative_positions: tuple[str, ...] = ()
    description: str = ""

    def __post_init__(self) -> None:
        _check_parts(self)
        _check_declaration(self)
        _check_runnable(self)
        _check_defaults(self)

    # ---- names --------------------------------------------------------------------------
    @property
    def state_names(self) -> tuple[str, ...]:
        """The mechanical state, ``[q_0, q_0', q_1, q_1', ...]`` (names with units)."""
        return tuple(n for c in self.coordinates for n in (c.name, c.rate_name))

    @property
    def dampers(self) -> tuple[Element, ...]:
        """The damper slots, in order: one action each."""
        return tuple(e for e in self.elements if e.kind == DAMPER)

    @property
    def packed_param_names(self) -> tuple[str, ...]:
        """What the compiled plant reads per vehicle, in packed order: the coordinates'
        inertias, then the springs' and dashpots' coefficients in element order."""
        inertias = tuple(c.inertia for c in self.coordinates)
        coefs = tuple(e.coefficient for e in self.elements if e.kind != DAMPER)
        return inertias + tuple(c for c in coefs if c is not None)

    def values(self, params: Any = None, **overrides: float) -> dict[str, float]:
        """``{parameter name: value}`` of ``params`` (default: the defaults), with
        ``overrides`` (e.g. a levitation stiffness scheduled with speed) taking precedence.
        Every number the vehicle reads must be a finite real number, each inertia > 0, the
        springs must hold every coordinate (the stiffness matrix with the guideway fixed
        positive definite: the vehicle rests on them) and each damper slot's ends must move
        apart in some motion; one ``ValueError`` or ``TypeError`` naming the parameter
        otherwise."""
        params = self.params() if params is None else params
        if not isinstance(params, self.params):
            raise TypeError(
                f"vehicle {self.name!r} reads {self.params.__name__}, got {type(params).__name__}"
            )
        out = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}
        unknown = sorted(set(overrides) - set(out))
        if unknown:
            raise ValueError(f"vehicle {self.name!r}: unknown parameter(s) {unknown}; accepted: "
                             f"{', '.join(sorted(out))}")  # fmt: skip
        out.update({k: v for k, v in overrides.items() if v is not None})
        for name in dict.fromkeys(self._read_names()):  # the numbers the equations read
            out[name] = check_real(f"vehicle {self.name!r}: {name}", out[name])
            if not math.isfinite(out[name]):
                raise ValueError(f"vehicle {self.name!r}: {name} must be finite, got {out[name]!r}")
        for c in self.coordinates:  # what the equations divide by
            if not out[c.inertia] > 0.0:
                raise ValueError(f"vehicle {self.name!r}: {c.inertia} must be a finite number "
                                 f"> 0, got {out[c.inertia]!r}")  # fmt: skip
        _check_held(self, out)
        for e in self.dampers:  # a slot that cannot move: its action would do nothing
            if not np.any(self.element_rows(e, out)[0]):
                raise ValueError(f"vehicle {self.name!r}: damper slot {e.name!r} joins {e.upper!r} "
                                 f"and {e.lower!r}, which move alike: its stroke is 0 in any "
                                 "motion")  # fmt: skip
        return out

    def _read_names(self) -> tuple[str, ...]:
        """Every parameter the vehicle reads: inertias, coefficients (the passive dampers'
        too) and the geometry's lever arms and offsets."""
        passive = tuple(e.passive for e in self.elements if e.passive is not None)
        return self.packed_param_names + passive + self._lever_arms()

    def _lever_arms(self) -> tuple[str, ...]:
        """The parameters the geometry reads (lever arms, contact offsets)."""
        terms = [c for p in self.points for _, c in p.terms] + [c.offset_m for c in self.contacts]
        return tuple(c for c in terms if isinstance(c, str))

    def as_array(self, params: Any = None) -> np.ndarray:
        """``params`` (default: the defaults) packed in :attr:`packed_param_names` order."""
        values = self.values(params)
        return np.array([float(values[n]) for n in self.packed_param_names])

    # ---- geometry -------------------------------------------------------------------------
    def point_row(self, name: str, values: dict[str, float]) -> np.ndarray:
        """The point's displacement as a row over the coordinates (``values``: :meth:`values`)."""
        index = {c.name: j for j, c in enumerate(self.coordinates)}
        point = next(p for p in self.points if p.name == name)
        row = np.zeros(len(self.coordinates))
        for coordinate, coefficient in point.terms:
            row[index[coordinate]] += _value(coefficient, values)
        return row

    def contact_offsets_m(self, params: Any = None) -> np.ndarray:
        """Each contact's longitudinal offset (m, > 0 ahead)."""
        values = self.values(params)
        return np.array([_value(c.offset_m, values) for c in self.contacts])

    def element_rows(
        self, element: Element, values: dict[str, float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(J, g)``: the element's deflection ``J q - g z_g`` (``g`` over the contacts)."""
        j = self.point_row(element.upper, values)
        g = np.zeros(len(self.contacts))
        contacts = [c.name for c in self.contacts]
        if element.lower in contacts:
            g[contacts.index(element.lower)] = 1.0
        else:
            j = j - self.point_row(element.lower, values)
        return j, g

    def with_name(self, name: str, **changes: Any) -> VehicleModel:
        """A copy under another name (e.g. to register a variant)."""
        return dataclasses.replace(self, name=name, **changes)


def _value(coefficient: float | str, values: dict[str, float]) -> float:
    return float(values[coefficient]) if isinstance(coefficient, str) else float(coefficient)


def _check_declaration(model: VehicleModel) -> None:
    """One clear ``ValueError`` for a declaration that names what it does not declare."""
    if not isinstance(model.name, str) or not model.name:
        raise ValueError(f"a vehicle model needs a non-empty name (a string), got {model.name!r}")
    if not dataclasses.is_dataclass(model.params):
        raise TypeError(f"vehicle {model.name!r}: params must be a dataclass type")
    fields = {f.name for f in dataclasses.fields(model.params)}
    coords = [c.name for c in model.coordinates]
    points = [p.name for p in model.points]
    contacts = [c.name for c in model.contacts]
    _check_names(model, coords, points, contacts)

    def need(name: object, where: str) -> None:
        if isinstance(name, str) and name not in fields:
            raise ValueError(
                f"vehicle {model.name!r}: {where} names {name!r}, not a field of "
                f"{model.params.__name__} ({', '.join(sorted(fields))})"
            )

    for c in model.coordinates:
        need(c.inertia, f"coordinate {c.name!r}")
    _check_points(model, coords, need)
    for c in model.contacts:
        need(c.offset_m, f"contact {c.name!r}")
    for e in model.elements:
        _check_element(model, e, points, contacts, need)
    missing = [p for p in model.comfort_points if p not in points]
    if missing:
        raise ValueError(f"vehicle {model.name!r}: comfort points {missing} are not points")


def _check_names(model: VehicleModel, coords: list, points: list, contacts: list) -> None:
    """At least one coordinate, each in metres or radians; every name used once."""
    if not coords:
        raise ValueError(f"vehicle {model.name!r}: declare at least one coordinate")
    for c in model.coordinates:
        if c.unit not in UNITS:
            raise ValueError(f"vehicle {model.name!r}: coordinate {c.name!r} unit must be one of "
                             f"{UNITS}, got {c.unit!r}")  # fmt: skip
    for what, names in (("coordinate and rate", coords + [c.rate_name for c in model.coordinates]),
                        ("point and contact", points + contacts),
                        ("element", [e.name for e in model.elements])):  # fmt: skip
        if len(set(names)) != len(names):
            raise ValueError(f"vehicle {model.name!r}: {what} names must be unique: {names}")


def _check_points(model: VehicleModel, coords: list, need) -> None:
    for p in model.points:
        for coordinate, coefficient in p.terms:
            if coordinate not in coords:
                raise ValueError(f"vehicle {model.name!r}: point {p.name!r} names {coordinate!r}, "
                                 f"not a coordinate ({', '.join(coords)})")  # fmt: skip
            need(coefficient, f"point {p.name!r}")


def _check_element(model: VehicleModel, e: Element, points: list, contacts: list, need) -> None:
    if e.kind not in (SPRING, DASHPOT, DAMPER):
        raise ValueError(f"vehicle {model.name!r}: element {e.name!r} kind must be one of "
                         f"{SPRING!r}, {DASHPOT!r}, {DAMPER!r}, got {e.kind!r}")  # fmt: skip
    if e.upper == e.lower:
        raise ValueError(f"vehicle {model.name!r}: element {e.name!r} joins {e.upper!r} to "
                         "itself")  # fmt: skip
    for field_name in ("coefficient", "passive"):
        value = getattr(e, field_name)
        if value is not None and not isinstance(value, str):
            raise TypeError(f"vehicle {model.name!r}: element {e.name!r} {field_name} must name "
                            f"a parameter (a string), got {value!r}")  # fmt: skip
    if e.upper not in points or e.lower not in points + contacts:
        raise ValueError(f"vehicle {model.name!r}: element {e.name!r} joins {e.upper!r} and "
                         f"{e.lower!r}; upper must be a point, lower a point or a contact")  # fmt: skip
    if e.kind == DAMPER and e.lower not in points:
        raise ValueError(f"vehicle {model.name!r}: damper slot {e.name!r} must join two points "
                         f"(a slot to the guideway, {e.lower!r}, is not supported)")  # fmt: skip
    if (e.kind == DAMPER) != (e.coefficient is None):
        raise ValueError(f"vehicle {model.name!r}: element {e.name!r}: a spring or dashpot "
                         "names its coefficient, a damper slot does not")  # fmt: skip
    need(e.coefficient, f"element {e.name!r}")
    need(e.passive, f"element {e.name!r}")


def _need_strings(part: Any, *fields: str) -> None:
    """Each of ``fields`` of a declared part is a non-empty string (``TypeError`` otherwise)."""
    for field_name in fields:
        value = getattr(part, field_name)
        if not isinstance(value, str) or not value:
            raise TypeError(f"{type(part).__name__} {field_name} must be a non-empty string, "
                            f"got {value!r}")  # fmt: skip


def _geometry_number(value: Any, what: str) -> None:
    """A lever arm or an offset: the name of a length parameter, or a finite real number."""
    if isinstance(value, str):
        return
    if not math.isfinite(check_real(what, value)):
        raise ValueError(f"{what} must be a finite number or a parameter's name, got {value!r}")


#: What each sequence of a :class:`VehicleModel` holds.
_PARTS = (("coordinates", Coordinate), ("points", Point), ("contacts", Contact),
          ("elements", Element), ("comfort_points", str), ("relative_positions", str))  # fmt: skip


def _check_parts(model: VehicleModel) -> None:
    """The name, the parameter class and each sequence's entries are of the declared types (a
    list is taken as the tuple it means, so that the model stays hashable)."""
    if not isinstance(model.name, str) or not model.name:
        raise ValueError(f"a vehicle model needs a non-empty name (a string), got {model.name!r}")
    if not (isinstance(model.params, type) and dataclasses.is_dataclass(model.params)):
        raise TypeError(f"vehicle {model.name!r}: params must be a dataclass type (the class, "
                        f"not an instance), got {model.params!r}")  # fmt: skip
    for field_name, kind in _PARTS:
        value = getattr(model, field_name)
        if not isinstance(value, (tuple, list)):
            raise TypeError(f"vehicle {model.name!r}: {field_name} must be a tuple of "
                            f"{kind.__name__}, got {value!r}")  # fmt: skip
        object.__setattr__(model, field_name, tuple(value))
        bad = [v for v in value if not isinstance(v, kind)]
        if bad:
            raise TypeError(f"vehicle {model.name!r}: {field_name} must hold {kind.__name__} "
                            f"entries, got {bad[0]!r}")  # fmt: skip


def _check_runnable(model: VehicleModel) -> None:
    """What the plant, the env and the controllers need: a damper slot (one action each), a
    contact, a comfort point, and ``relative_positions`` empty or naming each spring once, one
    per coordinate (:func:`capsule_env.vehicles.linear.relative_model`)."""
    for what, present in (("damper slot", model.dampers), ("guideway contact", model.contacts),
                          ("comfort point", model.comfort_points)):  # fmt: skip
        if not present:
            raise ValueError(f"vehicle {model.name!r}: declare at least one {what}")
    if len(set(model.comfort_points)) != len(model.comfort_points):
        raise ValueError(f"vehicle {model.name!r}: comfort_points must name each point once, "
                         f"got {model.comfort_points}")  # fmt: skip
    springs = [e.name for e in model.elements if e.kind == SPRING]
    rel = model.relative_positions
    if rel and (sorted(rel) != sorted(springs) or len(springs) != len(model.coordinates)):
        raise ValueError(f"vehicle {model.name!r}: relative_positions must name each of its "
                         f"{len(springs)} springs once, one per coordinate "
                         f"({len(model.coordinates)}), or be empty (then no relative form: no "
                         f"clipped LQR); got {rel}")  # fmt: skip


def _check_defaults(model: VehicleModel) -> None:
    """The parameter class's defaults are the vehicle's documented values: each must exist and
    pass :meth:`VehicleModel.values`."""
    try:
        defaults = model.params()
    except TypeError as exc:
        raise TypeError(f"vehicle {model.name!r}: params {model.params.__name__} must give every "
                        f"field a default (the documented value): {exc}") from None  # fmt: skip
    model.values(defaults)


def _check_held(model: VehicleModel, values: dict[str, float]) -> None:
    """``ValueError`` unless the springs' stiffness matrix (guideway fixed) is positive
    definite: a coordinate no spring holds, or a negative stiffness that tips the vehicle over,
    has no rest position (the env starts each episode there)."""
    n = len(model.coordinates)
    k = np.zeros((n, n))
    springs = [e for e in model.elements if e.kind == SPRING]
    rows = [model.element_rows(e, values)[0] for e in springs]
    for e, j in zip(springs, rows, strict=True):
        k += values[e.coefficient] * np.outer(j, j)  # type: ignore[index]
    eig, vec = np.linalg.eigh(k)
    if n and eig[0] > 1e-13 * np.abs(eig).max():
        return
    loose = np.abs(vec[:, 0]) > 1e-6 * np.abs(vec[:, 0]).max()
    names = ", ".join(c.name for c, free in zip(model.coordinates, loose, strict=True) if free)
    involved = [f"{e.coefficient} = {values[e.coefficient]!r}"  # type: ignore[index]
                for e, j in zip(springs, rows, strict=True) if np.any(j[loose])]  # fmt: skip
    raise ValueError(
        f"vehicle {model.name!r}: the springs do not hold {names} (the stiffness matrix with the "
        "guideway fixed must be positive definite, so that the vehicle rests on its springs); "
        f"the springs on them: {', '.join(involved) or 'none'}; stiffnesses must be > 0 N/m"
    )
