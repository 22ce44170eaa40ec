"""Side-view picture of the 1/4-car (car body, bogie, damper, springs, guideway) as RGB."""

from __future__ import annotations

from typing import Any

import numpy as np

from capsule_env.engine.layout import BODY_DISP, BOGIE_DISP, COIL_CURRENT, TIME

WIDTH, HEIGHT = 480, 360
_SKY = (236, 240, 245)
_BODY = (70, 110, 170)
_BOGIE = (90, 90, 100)
_DAMPER = (200, 120, 40)
_SPRING = (40, 150, 90)
_TRACK = (60, 60, 60)


def check_render_mode(render_mode: Any, drawn: bool = True) -> None:
    """``ValueError`` naming ``render_mode`` unless it is one an env draws: None or
    ``"rgb_array"`` (this side view), only None where the env draws nothing (``drawn=False``:
    a declared vehicle's)."""
    if render_mode is None:
        return
    if not drawn:
        raise ValueError(f"render_mode must be None for a declared vehicle, got {render_mode!r}")
    if render_mode != "rgb_array":
        raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")


def _rect(img: np.ndarray, x0: float, x1: float, y0: float, y1: float, color: tuple) -> None:
    h, w = img.shape[:2]
    xa, xb = sorted((int(round(x0)), int(round(x1))))
    ya, yb = sorted((int(round(y0)), int(round(y1))))
    img[max(ya, 0) : min(yb, h), max(xa, 0) : min(xb, w)] = color


def _vline(img: np.ndarray, x: float, y0: float, y1: float, color: tuple, width: float = 3) -> None:
    _rect(img, x - width / 2, x + width / 2, y0, y1, color)


def draw_quarter_car(
    car_body_displacement_m: float,
    bogie_displacement_m: float,
    guideway_elevation_m: np.ndarray,
    coil_current_fraction: float = 0.0,
    exaggeration: float = 4000.0,
) -> np.ndarray:
    """Return an ``(HEIGHT, WIDTH, 3)`` uint8 picture.

    Displacements are drawn ``exaggeration`` times larger (pixels per metre) so that the
    millimetre-scale motion is visible; the guideway strip shows ``guideway_elevation_m``
    sampled across the picture (the vehicle sits in the middle). The damper's colour darkens
    with the coil current (``coil_current_fraction`` in [0, 1]).
    """
    img = np.empty((HEIGHT, WIDTH, 3), dtype=np.uint8)
    img[:] = _SKY
    track_y = 300.0
    guide = np.asarray(guideway_elevation_m, float)
    xs = np.linspace(0, WIDTH - 1, guide.size).astype(int)
    for x, z in zip(xs, guide, strict=True):
        _rect(img, x - 2, x + 3, track_y - exaggeration * z, HEIGHT, _TRACK)
    zg_mid = guide[guide.size // 2] if guide.size else 0.0
    bogie_y = 240.0 - exaggeration * bogie_displacement_m
    body_y = 110.0 - exaggeration * car_body_displacement_m
    cx = WIDTH / 2
    # levitation "spring" (EDS): dashed green between guideway and bogie
    for y in np.arange(bogie_y + 20, track_y - exaggeration * zg_mid, 8):
        _rect(img, cx - 30, cx - 22, y, y + 4, _SPRING)
        _rect(img, cx + 22, cx + 30, y, y + 4, _SPRING)
    # secondary spring (left) and MR damper (right) between bogie and body
    for y in np.arange(body_y + 60, bogie_y, 10):
        _rect(img, cx - 70, cx - 40, y, y + 4, _SPRING)
    frac = float(np.clip(coil_current_fraction, 0.0, 1.0))
    damper = tuple(int(c * (1.0 - 0.6 * frac)) for c in _DAMPER)
    _rect(img, cx + 40, cx + 70, (body_y + 60 + bogie_y) / 2, bogie_y, damper)
    _vline(img, cx + 55, body_y + 60, (body_y + 60 + bogie_y) / 2, damper, width=6)
    _rect(img, cx - 140, cx + 140, body_y, body_y + 60, _BODY)
    _rect(img, cx - 90, cx + 90, bogie_y, bogie_y + 20, _BOGIE)
    return img


def render_vehicle(batch: Any, n: int) -> np.ndarray:
    """The picture of vehicle ``n`` of a :class:`capsule_env.engine.batch.CapsuleBatch`: its car body
    and bogie now, 60 m of guideway around it and the coil current as the damper's colour."""
    span = np.linspace(-30.0, 30.0, 121)
    profile = batch.profiles[batch.profile_index[n]]
    t = batch.state[n, TIME]
    position = batch.start_position[n] + batch.speed[n] * t + span
    elevation = batch.gain[n] * np.interp(
        position / batch.spacing, np.arange(profile.size), profile
    )
    return draw_quarter_car(
        batch.state[n, BODY_DISP],
        batch.state[n, BOGIE_DISP],
        elevation,
        coil_current_fraction=batch.state[n, COIL_CURRENT] / max(batch.i_max, 1e-9),
    )
