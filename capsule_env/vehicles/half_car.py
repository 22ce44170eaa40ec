"""The built-in ``half_car``: the capsule's car body in heave and pitch on two bogies, each on
its own EDS levitation (docs/model.md, section 2.1), declared as data
(:mod:`capsule_env.vehicles.declaration`).

Sign convention: ``x`` is the longitudinal position, positive ahead of the car body's centre
of mass; heave ``z`` is up positive; the pitch ``theta`` is positive **nose up**, so that a
point of the body at ``x`` moves by ``z_c + x theta``. The front bogie sits at
``x = a`` (``front_bogie_position_m``), the rear one at ``x = -b`` (``rear_bogie_position_m``,
a negative number). Each bogie's guideway contact is at its own position, so the rear bogie
meets the profile the front one met ``(a + b) / v`` earlier::

    m   z_c''   = -k_sf d_sf - F_f - k_sr d_sr - F_r
    I   theta'' = -a (k_sf d_sf + F_f) + b (k_sr d_sr + F_r)
    m_f z_bf''  =  k_sf d_sf + F_f - k_pf (z_bf - z_gf) - c_pf (z_bf' - z_gf')
    m_r z_br''  =  k_sr d_sr + F_r - k_pr (z_br - z_gr) - c_pr (z_br' - z_gr')

    d_sf = z_c + a theta - z_bf,   d_sr = z_c - b theta - z_br,   z_gr(t) = z_gf(t - (a + b) / v)

with ``F_f``, ``F_r`` the damper forces (positive when they resist a positive stroke rate).

**One side of the capsule.** The paper's 1/4-car is one corner of a capsule on two bogies
(front or rear, left or right). This half-car is one *side* (left or right) of that capsule:
two corners, each exactly the paper's 1/4-car in its values (2400 kg of bogie, the springs,
the passive damper and the levitation of one corner), on one body of 2 x 6000 kg. With the
left and right sides alike, the whole capsule's heave and pitch are these motions (every mass,
inertia, stiffness and damping of the whole is twice this side's: the same modes, the same
accelerations); a damper slot is one corner's damper (the whole capsule has two per bogie).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from capsule_env.common.validation import check_choice, check_in_range, check_positive
from capsule_env.vehicles.declaration import (
    DAMPER,
    DASHPOT,
    SPRING,
    Contact,
    Coordinate,
    Element,
    Point,
    VehicleModel,
)
from capsule_env.vehicles.quarter_car import _RANGES as _QUARTER_RANGES
from capsule_env.vehicles.quarter_car import VehicleParams

__all__ = ["HalfCarParams", "MODEL", "BOGIES"]

#: The bogies, in the order of the damper slots (one action each) and of the contacts.
BOGIES = ("front", "rear")

#: A corner's fields, named as :class:`~capsule_env.vehicles.quarter_car.VehicleParams` names
#: them (each prefixed by its bogie in :class:`HalfCarParams`).
_CORNER_FIELDS = (
    "bogie_mass_kg",
    "secondary_stiffness_n_per_m",
    "levitation_stiffness_n_per_m",
    "passive_damping_n_s_per_m",
    "levitation_damping_n_s_per_m",
)

#: Accepted range of each :class:`HalfCarParams` field (SI units): each corner's are the
#: 1/4-car's. The bogies' positions are signed: the front one ahead of the centre of mass, the
#: rear one behind it.
_RANGES = {
    "car_body_mass_kg": _QUARTER_RANGES["car_body_mass_kg"],
    "car_body_pitch_inertia_kg_m2": (1.0, 1e9),
    "front_bogie_position_m": (0.01, 100.0),
    "rear_bogie_position_m": (-100.0, -0.01),
    **{f"{side}_{name}": _QUARTER_RANGES[name] for side in BOGIES for name in _CORNER_FIELDS},
}


@dataclass(frozen=True)
class HalfCarParams:
    """Parameters of the half-car capsule (one side; module doc). Provenance in docs/model.md,
    section 2.1; every field can be overridden.

    Attributes
    ----------
    car_body_mass_kg : m, the car body's mass on this side (kg), default 12000: two of the
        paper's 1/4-car bodies (6000 kg each) [reconstructed].
    car_body_pitch_inertia_kg_m2 : I, its pitch moment of inertia about the centre of mass
        (kg m^2), default 9.0e5 = m L^2 / 12 with L = 30 m: a uniform body of the length of
        HyperloopTT's published capsule (30 m) [reconstructed]; with the default bogie
        positions this is a dynamic index ``I / (m a b)`` of 0.75.
    front_bogie_position_m : a, the front bogie's position ahead of the centre of mass (m),
        default 10.0 [reconstructed; no published capsule gives its bogie positions].
    rear_bogie_position_m : -b, the rear bogie's position (m, negative: behind the centre of
        mass), default -10.0 [reconstructed]. Bogie centres 20 m apart on a 30 m capsule.
    front_bogie_mass_kg, rear_bogie_mass_kg : each bogie's mass on this side (kg), default
        2400: the paper's 1/4-car bogie.
    front_secondary_stiffness_n_per_m, rear_... : k_s of each corner (N/m), default 4.95e5.
    front_levitation_stiffness_n_per_m, rear_... : k_p, the EDS levitation of each bogie at
        810 km/h (N/m), default 2.25e6. The speed-dependent option sets it (and the damping
        below) per speed, one coil model per bogie (:meth:`quarter_params` gives each bogie's
        1/4-car for :func:`capsule_env.envelope.levitation.eds_coil`).
    front_passive_damping_n_s_per_m, rear_... : c_s, the passive damper in each slot for
        the linear passive plant (N s/m; pass it as ``slot_damping`` to ``absolute_model``),
        default 1.5e4; not part of the MR-damped plant. The env's ``damper="passive"`` reads
        ``damper_params`` (the same 1.5e4 by default), not these: change both.
    front_levitation_damping_n_s_per_m, rear_... : c_p (N s/m), default 0 (the paper's
        undamped levitation); -2e4 to 2e4, as for the 1/4-car.

    Notes
    -----
    Accepted ranges: masses 1 kg to 1e6 kg, pitch inertia 1 to 1e9 kg m^2, the front bogie
    0.01 to 100 m ahead and the rear one 0.01 to 100 m behind the centre of mass, stiffnesses
    1 to 1e10 N/m, passive damping 0 to 1e9 N s/m, levitation damping -2e4 to 2e4 N s/m
    (``ValueError`` naming the field otherwise). The pitch inertia does not follow the mass or
    the bogie positions when they are changed: set it (or use :meth:`from_quarter_car`).
    """

    car_body_mass_kg: float = 12000.0
    car_body_pitch_inertia_kg_m2: float = 9.0e5
    front_bogie_position_m: float = 10.0
    rear_bogie_position_m: float = -10.0
    front_bogie_mass_kg: float = 2400.0
    rear_bogie_mass_kg: float = 2400.0
    front_secondary_stiffness_n_per_m: float = 4.95e5
    rear_secondary_stiffness_n_per_m: float = 4.95e5
    front_levitation_stiffness_n_per_m: float = 2.25e6
    rear_levitation_stiffness_n_per_m: float = 2.25e6
    front_passive_damping_n_s_per_m: float = 1.5e4
    rear_passive_damping_n_s_per_m: float = 1.5e4
    front_levitation_damping_n_s_per_m: float = 0.0
    rear_levitation_damping_n_s_per_m: float = 0.0

    def __post_init__(self) -> None:
        for name, (low, high) in _RANGES.items():
            check_in_range(name, getattr(self, name), low, high)

    # ---- geometry ---------------------------------------------------------------------------
    @property
    def front_lever_arm_m(self) -> float:
        """``a``: the front bogie's distance ahead of the centre of mass (m)."""
        return float(self.front_bogie_position_m)

    @property
    def rear_lever_arm_m(self) -> float:
        """``b``: the rear bogie's distance behind the centre of mass (m)."""
        return -float(self.rear_bogie_position_m)

    @property
    def bogie_spacing_m(self) -> float:
        """``a + b``: the distance between the bogie centres (m)."""
        return self.front_lever_arm_m + self.rear_lever_arm_m

    @property
    def dynamic_index(self) -> float:
        """``k^2 / (a b) = I / (m a b)``: 1 decouples the two ends (each then moves on its own
        bogie as a 1/4-car of body mass ``m b / (a + b)`` in front, ``m a / (a + b)`` behind)."""
        a, b = self.front_lever_arm_m, self.rear_lever_arm_m
        return self.car_body_pitch_inertia_kg_m2 / (self.car_body_mass_kg * a * b)

    def wheelbase_delay_s(self, speed_m_s: float) -> float:
        """``(a + b) / v``: how much later the rear bogie meets the guideway the front one met
        (s); ``speed_m_s`` > 0."""
        return self.bogie_spacing_m / check_positive("speed_m_s", speed_m_s)

    # ---- the halves -----------------------------------------------------------------------
    @classmethod
    def from_quarter_car(
        cls,
        quarter: VehicleParams | None = None,
        front_bogie_position_m: float = 10.0,
        rear_bogie_position_m: float = -10.0,
        dynamic_index: float = 0.75,
    ) -> HalfCarParams:
        """Equal halves: each corner is ``quarter`` (default: the paper's 1/4-car), the body
        twice its body, the pitch inertia ``dynamic_index * m a b`` (``dynamic_index`` in
        [0.05, 20])."""
        quarter = VehicleParams() if quarter is None else quarter
        check_in_range("dynamic_index", dynamic_index, 0.05, 20.0)
        mass = 2.0 * quarter.car_body_mass_kg
        a, b = float(front_bogie_position_m), -float(rear_bogie_position_m)
        corner = {name: getattr(quarter, name) for name in _CORNER_FIELDS}
        return cls(
            car_body_mass_kg=mass,
            car_body_pitch_inertia_kg_m2=dynamic_index * mass * a * b,
            front_bogie_position_m=front_bogie_position_m,
            rear_bogie_position_m=rear_bogie_position_m,
            **{f"{side}_{name}": value for side in BOGIES for name, value in corner.items()},
        )

    def quarter_params(self, bogie: str) -> VehicleParams:
        """The 1/4-car of one bogie (``"front"`` or ``"rear"``): its corner's values and the
        share of the body it carries statically, ``m b / (a + b)`` in front and
        ``m a / (a + b)`` behind (what its levitation lifts, e.g. to calibrate an EDS coil
        model). At a dynamic index of 1 it is also the 1/4-car that end moves as, exactly."""
        check_choice("bogie", bogie, BOGIES)
        other = self.rear_lever_arm_m if bogie == "front" else self.front_lever_arm_m
        return VehicleParams(
            car_body_mass_kg=self.car_body_mass_kg * other / self.bogie_spacing_m,
            **{name: getattr(self, f"{bogie}_{name}") for name in _CORNER_FIELDS},
        )

    def with_levitation(
        self, stiffness_n_per_m: float, damping_n_s_per_m: float = 0.0
    ) -> HalfCarParams:
        """A copy with both bogies' levitation at ``stiffness_n_per_m`` and
        ``damping_n_s_per_m`` (e.g. the EDS model's at one speed; identical bogies)."""
        return dataclasses.replace(
            self,
            **{f"{side}_levitation_stiffness_n_per_m": stiffness_n_per_m for side in BOGIES},
            **{f"{side}_levitation_damping_n_s_per_m": damping_n_s_per_m for side in BOGIES},
        )


def _bogie_elements(side: str) -> tuple[Element, ...]:
    """One corner, in the 1/4-car's order: secondary spring, damper slot, levitation spring,
    levitation dashpot."""
    body, bogie, guideway = f"{side}_car_body", f"{side}_bogie", f"{side}_guideway"
    return (
        Element(SPRING, f"{side}_secondary_spring", body, bogie,
                f"{side}_secondary_stiffness_n_per_m"),
        Element(DAMPER, f"{side}_secondary_damper", body, bogie,
                passive=f"{side}_passive_damping_n_s_per_m"),
        Element(SPRING, f"{side}_levitation_spring", bogie, guideway,
                f"{side}_levitation_stiffness_n_per_m"),
        Element(DASHPOT, f"{side}_levitation_damping", bogie, guideway,
                f"{side}_levitation_damping_n_s_per_m"),
    )  # fmt: skip


_Z, _THETA = "car_body_displacement_m", "car_body_pitch_rad"

MODEL = VehicleModel(
    name="half_car",
    params=HalfCarParams,
    coordinates=(
        Coordinate(_Z, "m", "car_body_mass_kg", "car_body_velocity_m_s"),
        Coordinate(_THETA, "rad", "car_body_pitch_inertia_kg_m2", "car_body_pitch_rate_rad_s"),
        Coordinate(
            "front_bogie_displacement_m", "m", "front_bogie_mass_kg", "front_bogie_velocity_m_s"
        ),
        Coordinate(
            "rear_bogie_displacement_m", "m", "rear_bogie_mass_kg", "rear_bogie_velocity_m_s"
        ),
    ),  # fmt: skip
    points=(
        Point("car_body", ((_Z, 1.0),)),
        Point("front_car_body", ((_Z, 1.0), (_THETA, "front_bogie_position_m"))),
        Point("rear_car_body", ((_Z, 1.0), (_THETA, "rear_bogie_position_m"))),
        Point("front_bogie", (("front_bogie_displacement_m", 1.0),)),
        Point("rear_bogie", (("rear_bogie_displacement_m", 1.0),)),
    ),
    contacts=(
        Contact("front_guideway", "front_bogie_position_m"),
        Contact("rear_guideway", "rear_bogie_position_m"),
    ),
    elements=_bogie_elements("front") + _bogie_elements("rear"),
    comfort_points=("front_car_body", "car_body", "rear_car_body"),
    relative_positions=(
        "front_secondary_spring",
        "rear_secondary_spring",
        "front_levitation_spring",
        "rear_levitation_spring",
    ),
    description=(
        "One side of a capsule on two bogies: car body heave and pitch, each bogie on its own "
        "EDS levitation, one secondary spring and one damper slot per bogie; the rear contact "
        "meets the front's profile (a + b) / speed later."
    ),
)
