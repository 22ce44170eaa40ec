"""Which declared vehicles the compiled plant runs today.

The compiled kernels (:mod:`capsule_env.plant`) integrate one form: two coordinates (a body on a
bogie), the secondary spring and one damper slot between them, the levitation's spring and
dashpot from the bogie to one guideway contact at the reference point, the comfort point on the
body. Any registered vehicle of that form runs through the env (``gym.make(...,
vehicle=name)``), its parameters packed by its own declaration; a vehicle of another form (a
third body, a pitching car with two bogies) has a linear model (controllers, modes, the
reference solver) but is refused by the env, by name.
"""

from __future__ import annotations

from capsule_env.vehicles.declaration import VehicleModel

__all__ = ["form_of", "check_compiled"]


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


def check_compiled(model: VehicleModel, params: object = None) -> VehicleModel:
    """``model`` if the compiled plant runs it with ``params`` (default: its defaults; a lever
    arm or a contact offset among them may change the form), else one ``ValueError`` saying
    why."""
    from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR

    if form_of(model, params) != form_of(QUARTER_CAR):
        raise ValueError(
            f"vehicle {model.name!r}: the env's compiled plant runs vehicles of the quarter_car's "
            "form (a body on a bogie: 2 coordinates, the secondary spring and one damper slot "
            "between them, the levitation spring and dashpot to one contact at offset 0); "
            f"{model.name!r} has {len(model.coordinates)} coordinates, "
            f"{len(model.dampers)} damper slot(s) and {len(model.contacts)} contact(s) (its "
            "lever arms and contact offsets at the parameters given count too). Its linear "
            "model (capsule_env.vehicles.absolute_model) serves the controllers."
        )
    return model
