"""Which declared vehicles the quarter-car's vectorised kernels run.

Those kernels (:mod:`capsule_env.plant.block`, :mod:`capsule_env.plant.scalar`, the env's
``CapsuleBatch``) integrate one form, unrolled for speed: two coordinates (a body on a bogie),
the secondary spring and one damper slot between them, the levitation's spring and dashpot from
the bogie to one guideway contact at the reference point, the comfort point on the body. Any
registered vehicle of that form runs through them, its parameters packed by its own
declaration. A vehicle of any other form (a third body, a pitching car on two bogies) runs on
the declared plant (:mod:`capsule_env.plant.declared`, compiled from its declaration), through
:class:`capsule_env.envs.declared_vehicle.DeclaredVehicleEnv`: ``gym.make("CapsuleSuspension-v0",
vehicle=name)`` picks the one that runs it.
"""

from __future__ import annotations

from capsule_env.vehicles.declaration import VehicleModel

__all__ = ["form_of", "runs_compiled", "check_compiled"]


def form_of(model: VehicleModel, params: object = None) -> tuple:
    """The declaration's structure without its names, its geometry at ``params`` (default: the
    defaults): what a kernel's arithmetic depends on."""
    values = model.values(params)
    coords = [c.name for c in model.coordinates]
    points = [p.name for p in model.points]
    ends = points + [c.name for c in model.contacts]
    rows = tuple(tuple(model.point_row(p, values)) for p in points)
    elements = tuple((e.kind, ends.index(e.upper), ends.index(e.lower), e.coefficient is None)
                     for e in model.elements)  # fmt: skip
    return (len(coords), rows, tuple(model.contact_offsets_m(params)), elements,
            tuple(points.index(p) for p in model.comfort_points))  # fmt: skip


def runs_compiled(model: VehicleModel, params: object = None) -> bool:
    """Whether the quarter-car's compiled kernels run ``model`` at ``params`` (default: its
    defaults): whether it has the quarter-car's form."""
    from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR

    return form_of(model, params) == form_of(QUARTER_CAR)


def check_compiled(model: VehicleModel, params: object = None) -> VehicleModel:
    """``model`` if the compiled plant runs it with ``params`` (default: its defaults; a lever
    arm or a contact offset among them may change the form), else one ``ValueError`` saying
    why."""
    if not runs_compiled(model, params):
        raise ValueError(
            f"vehicle {model.name!r}: the env's compiled plant runs vehicles of the quarter_car's "
            "form (a body on a bogie: 2 coordinates, the secondary spring and one damper slot "
            "between them, the levitation spring and dashpot to one contact at offset 0); "
            f"{model.name!r} has {len(model.coordinates)} coordinates, "
            f"{len(model.dampers)} damper slot(s) and {len(model.contacts)} contact(s) (its "
            "lever arms and contact offsets at the parameters given count too). "
            "gym.make('CapsuleSuspension-v0', vehicle=...) runs it on the declared plant "
            "(capsule_env.envs.declared_vehicle.DeclaredVehicleEnv)."
        )
    return model
