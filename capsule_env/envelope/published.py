"""The EDS levitation model checked against its own neglected physics and published figures.

Four checks of :mod:`capsule_env.envelope.levitation` (issue 43, item 4; the tables and the
figure are in docs/envelope.md, "The levitation against published data"):

- **The coil's dynamics.** The env's levitation is quasi-static: a spring ``k_p(v)`` and a
  damper ``c_p(v)``, the first order of the coil's response in the heave frequency ``W`` over
  the electrical frequency ``w = k v`` (``k = pi / pole_pitch``). The same single L-R circuit
  has an exact linearised response: with the flux linkage ``a z(t) cos(w t)``, a heave
  ``z = z0 + dz e^{j W t}`` drives the current at ``w + W`` and ``W - w``; each goes through the
  circuit's admittance and beats with ``cos(w t)`` back down to ``W``, so that the restoring
  force is ``K(jW) dz`` with (``p = 1 / tau = R / L``, ``K_inf = a^2 / (2 L)``)

  .. math::

      K(s) = \\frac{K_\\infty}{2}\\left[\\frac{(s + j w)\\tau}{1 + (s + j w)\\tau}
             + \\frac{(s - j w)\\tau}{1 + (s - j w)\\tau}\\right]
           = K_\\infty \\frac{s (s + p) + w^2}{(s + p)^2 + w^2}.

  ``K(0) = k_p`` and ``K'(0) = c_p``: the quasi-static model is its first-order Taylor
  expansion (:func:`dynamic_stiffness_n_per_m`, tested against a simulation of the circuit).
  The force ripple at ``2 w +- W`` is left out (it averages out over the many coils a magnet
  passes, and lies far above the body's modes).
- **The magnet's length.** A magnet of length ``L`` sees the guideway's height averaged over
  ``L``: a moving average, gain ``sinc(pi L / lambda)`` at wavelength ``lambda``
  (:func:`magnet_length_gain`). By default the env has no such filter (the bogie reads the
  profile at a point); the option ``magnet_length_m`` applies it
  (:mod:`capsule_env.envelope.magnet`).
- **Lift-off under payload.** The linear coil's force at the sag ``z`` is ``k_p(v) z``; the
  capsule leaves its wheels when the sag ``W / k_p(v)`` is at most the travel the wheels leave
  (:func:`lift_off_speed_m_s`).
- **Lift over drag** at the equilibrium sag, ``r / (k z_eq)`` (:func:`lift_over_drag`).

The Wk effect of the first two is computed on the linear quarter car (passive damper, FRA
class-6 guideway PSD over the env's 2-500 m band, ISO 2631-1 Wk): :func:`wk_ratio`. Run
``python -m capsule_env.envelope.published [--figure PATH]`` for the tables (Markdown, on
stdout) and the figure. Pure numpy (matplotlib for the figure only).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from capsule_env.common.cli import ArgumentParser
from capsule_env.common.safe_io import check_writable_file
from capsule_env.common.units import kmh_to_m_s, m_s_to_kmh
from capsule_env.common.validation import check_in_range
from capsule_env.envelope.levitation import (
    GRAVITY_M_S2,
    EdsCoil,
    eds_coil,
    equilibrium_sag_m,
    levitation_damping_n_s_per_m,
    levitation_stiffness_n_per_m,
    lift_off_speed_m_s,
)
from capsule_env.guideway.random import fra_psd
from capsule_env.metrics import wk_weighting
from capsule_env.vehicles import VehicleParams

__all__ = [
    "dynamic_stiffness_n_per_m",
    "quasi_static_stiffness_n_per_m",
    "magnet_length_gain",
    "lift_off_speed_m_s",
    "lift_over_drag",
    "mode_frequencies_hz",
    "wk_ratio",
    "TABLE_SPEEDS_KMH",
]

#: The speeds of the tables (km/h): the envelope study's.
TABLE_SPEEDS_KMH = (150.0, 200.0, 300.0, 400.0, 600.0, 810.0, 1000.0, 1200.0)
#: The env's random guideway band (m), :class:`capsule_env.guideway.params.GuidewayParams`.
_BAND_M = (2.0, 500.0)


def dynamic_stiffness_n_per_m(frequency_hz, speed_m_s: float, coil: EdsCoil) -> np.ndarray:
    """The coil's exact linearised dynamic stiffness ``K(j 2 pi f)`` (N/m, complex) at the
    heave frequencies ``frequency_hz``: ``K_inf (s (s + p) + w^2) / ((s + p)^2 + w^2)``."""
    s = 2j * np.pi * np.asarray(frequency_hz, dtype=float)
    p = 1.0 / coil.time_constant_s
    w = coil.wavenumber_per_m * speed_m_s
    return coil.stiffness_limit_n_per_m * (s * (s + p) + w * w) / ((s + p) ** 2 + w * w)


def quasi_static_stiffness_n_per_m(frequency_hz, speed_m_s: float, coil: EdsCoil) -> np.ndarray:
    """What the env uses: ``k_p(v) + j 2 pi f c_p(v)`` (N/m, complex)."""
    s = 2j * np.pi * np.asarray(frequency_hz, dtype=float)
    return levitation_stiffness_n_per_m(speed_m_s, coil) + s * levitation_damping_n_s_per_m(
        speed_m_s, coil
    )


def magnet_length_gain(wavelength_m, magnet_length_m: float) -> np.ndarray:
    """Gain of a moving average over ``magnet_length_m`` at ``wavelength_m``:
    ``sin(x) / x``, ``x = pi L / lambda`` (signed; 1 for ``L = 0``)."""
    check_in_range("magnet_length_m", magnet_length_m, 0.0, 100.0)
    return np.sinc(magnet_length_m / np.asarray(wavelength_m, dtype=float))


def lift_over_drag(speed_m_s, coil: EdsCoil) -> np.ndarray:
    """Lift over magnetic drag at the equilibrium sag: ``r / (k z_eq)`` (the weight over
    :func:`capsule_env.envelope.levitation.magnetic_drag_n`)."""
    r = np.asarray(speed_m_s, dtype=float) / coil.characteristic_speed_m_s
    return r / (coil.wavenumber_per_m * equilibrium_sag_m(speed_m_s, coil))


def mode_frequencies_hz(stiffness_n_per_m: float, vehicle: VehicleParams) -> np.ndarray:
    """The undamped body and bogie modes (Hz, ascending) of the quarter car on a levitation
    spring ``stiffness_n_per_m``."""
    m = np.array([vehicle.car_body_mass_kg, vehicle.bogie_mass_kg])
    ks = vehicle.secondary_stiffness_n_per_m
    k = np.array([[ks, -ks], [-ks, ks + stiffness_n_per_m]])
    eig = np.linalg.eigvals(k / np.sqrt(np.outer(m, m)))
    return np.sort(np.sqrt(eig.real)) / (2.0 * np.pi)


def _body_acceleration(frequency_hz: np.ndarray, levitation: np.ndarray,
                       vehicle: VehicleParams) -> np.ndarray:  # fmt: skip
    """The body's acceleration per unit guideway height (1/s^2, complex) of the quarter car
    with the passive damper and a levitation of dynamic stiffness ``levitation``."""
    s = 2j * np.pi * frequency_hz
    secondary = vehicle.secondary_stiffness_n_per_m + s * vehicle.passive_damping_n_s_per_m
    body = vehicle.car_body_mass_kg * s**2 + secondary
    bogie = vehicle.bogie_mass_kg * s**2 + secondary + levitation
    return s**2 * secondary * levitation / (body * bogie - secondary**2)


def _wk_rms(speed_m_s: float, levitation: Callable[[np.ndarray], np.ndarray],
            vehicle: VehicleParams, magnet_length_m: float, n: int) -> float:  # fmt: skip
    """Wk-weighted RMS body acceleration (m/s^2) over the unscaled FRA class-6 band."""
    wavenumber = np.linspace(2 * np.pi / _BAND_M[1], 2 * np.pi / _BAND_M[0], n)
    f = speed_m_s * wavenumber / (2 * np.pi)
    h = _body_acceleration(f, levitation(f), vehicle) * wk_weighting(f)
    h = h * magnet_length_gain(2 * np.pi / wavenumber, magnet_length_m)
    return float(
        np.sqrt(np.sum(np.abs(h) ** 2 * fra_psd(wavenumber)) * (wavenumber[1] - wavenumber[0]))
    )


def wk_ratio(speed_m_s: float, coil: EdsCoil, vehicle: VehicleParams | None = None, *,
             dynamic: bool = False, magnet_length_m: float = 0.0, n: int = 200_000) -> float:  # fmt: skip
    """The linear quarter car's Wk-weighted RMS body acceleration with the coil's dynamics
    (``dynamic``) and/or a magnet of ``magnet_length_m``, over the env's (quasi-static, point
    magnet); the passive damper, the FRA class-6 PSD over the 2-500 m band."""
    vehicle = vehicle or VehicleParams()

    def quasi(f):
        return quasi_static_stiffness_n_per_m(f, speed_m_s, coil)

    def exact(f):
        return dynamic_stiffness_n_per_m(f, speed_m_s, coil)

    base = _wk_rms(speed_m_s, quasi, vehicle, 0.0, n)
    return _wk_rms(speed_m_s, exact if dynamic else quasi, vehicle, magnet_length_m, n) / base


# ------------------------------------------------------------------------------ the tables
def _row(cells: Sequence[object]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def dynamics_table(coil: EdsCoil, vehicle: VehicleParams) -> list[str]:
    """Markdown rows: at each speed and mode, ``W / w``, the error of the quasi-static
    ``|K|`` and its phase against the exact ``K(jW)``, and the damping each implies."""
    lines = [_row(["speed (km/h)", "mode", "f (Hz)", "W / w", "abs K: qs / exact - 1",
                   "phase qs - exact (deg)", "c_p (N s/m)", "Im K / W exact (N s/m)"]),
             _row(["---:", "---", "---:", "---:", "---:", "---:", "---:", "---:"])]  # fmt: skip
    for kmh in TABLE_SPEEDS_KMH:
        v = kmh_to_m_s(kmh)
        modes = mode_frequencies_hz(float(levitation_stiffness_n_per_m(v, coil)), vehicle)
        for name, f in zip(("body", "bogie"), modes):
            exact = complex(dynamic_stiffness_n_per_m(f, v, coil))
            quasi = complex(quasi_static_stiffness_n_per_m(f, v, coil))
            lines.append(_row([f"{kmh:g}", name, f"{f:.2f}",
                               f"{2 * np.pi * f / (coil.wavenumber_per_m * v):.3f}",
                               f"{abs(quasi) / abs(exact) - 1:+.2%}",
                               f"{math.degrees(np.angle(quasi / exact)):+.3f}",
                               f"{float(levitation_damping_n_s_per_m(v, coil)):.0f}",
                               f"{exact.imag / (2 * np.pi * f):.0f}"]))  # fmt: skip
    return lines


def wk_table(coil: EdsCoil, vehicle: VehicleParams, lengths_m: Sequence[float]) -> list[str]:
    """Markdown rows: the Wk ratios of :func:`wk_ratio` against speed."""
    lines = [_row(["speed (km/h)", "coil dynamics", *(f"magnet {x:g} m" for x in lengths_m)]),
             _row(["---:"] * (2 + len(lengths_m)))]  # fmt: skip
    for kmh in TABLE_SPEEDS_KMH:
        v = kmh_to_m_s(kmh)
        cells = [wk_ratio(v, coil, vehicle, dynamic=True)]
        cells += [wk_ratio(v, coil, vehicle, magnet_length_m=x) for x in lengths_m]
        lines.append(_row([f"{kmh:g}", *(f"{c:.4f}" for c in cells)]))
    return lines


def payload_table(vehicle: VehicleParams, payloads: Sequence[float], travel_m: float,
                  lift_off_kmh: float) -> list[str]:  # fmt: skip
    """Markdown rows: per payload (the car body's mass times ``1 + u``), the sag at the
    lift-off speed, the lift the travel allows there over the weight, and the speed at
    which the sag equals the travel (the coil calibrated on the unladen vehicle, as in the
    env: the payload changes the mass, not the coil)."""
    coil = eds_coil(vehicle)
    v_lo = kmh_to_m_s(lift_off_kmh)
    k_lo = float(levitation_stiffness_n_per_m(v_lo, coil))
    lines = [_row(["payload", "weight (kN)", f"sag at {lift_off_kmh:g} km/h (m)",
                   "lift at the travel / weight", "lift-off speed (km/h)"]),
             _row(["---:"] * 5)]  # fmt: skip
    for u in payloads:
        weight = (vehicle.car_body_mass_kg * (1 + u) + vehicle.bogie_mass_kg) * GRAVITY_M_S2
        lines.append(_row([f"{u:+.0%}", f"{weight / 1e3:.1f}", f"{weight / k_lo:.4f}",
                           f"{k_lo * travel_m / weight:.3f}",
                           f"{m_s_to_kmh(lift_off_speed_m_s(coil, weight, travel_m)):.1f}"]))  # fmt: skip
    return lines


# ------------------------------------------------------------------------------ the figure
_FONT = 11  # pt: legible at the docs' 736 px width for a 1000 px figure


def _stiffness_panels(axes, coil: EdsCoil, vehicle: VehicleParams) -> None:
    f = np.logspace(-0.5, 2.0, 400)
    for kmh, colour in ((150.0, "tab:red"), (810.0, "tab:blue")):
        v = kmh_to_m_s(kmh)
        k_p = float(levitation_stiffness_n_per_m(v, coil))
        exact, quasi = (
            dynamic_stiffness_n_per_m(f, v, coil),
            quasi_static_stiffness_n_per_m(f, v, coil),
        )
        axes[0].semilogx(f, np.abs(exact) / k_p, color=colour, label=f"exact, {kmh:g} km/h")
        axes[0].semilogx(f, np.abs(quasi) / k_p, "--", color=colour, label=f"quasi-static, {kmh:g}")
        axes[1].semilogx(f, np.degrees(np.angle(exact)), color=colour)
        axes[1].semilogx(f, np.degrees(np.angle(quasi)), "--", color=colour)
        for mode in mode_frequencies_hz(k_p, vehicle):
            for ax in axes:
                ax.axvline(mode, color=colour, lw=0.8, ls=":")
    axes[0].set_ylabel("|K(jW)| / k_p(v)", fontsize=_FONT)
    axes[0].set_ylim(0.0, 3.0)
    axes[1].set_ylabel("phase of K (deg)", fontsize=_FONT)
    axes[1].set_ylim(-60.0, 60.0)
    axes[0].legend(fontsize=_FONT - 1, loc="upper left")
    for ax in axes:
        ax.set_xlabel("heave frequency (Hz); dotted: the modes", fontsize=_FONT)


def _wk_panel(ax, coil: EdsCoil, vehicle: VehicleParams, lengths_m: Sequence[float]) -> None:
    speeds = np.array(TABLE_SPEEDS_KMH)
    ratios = [wk_ratio(kmh_to_m_s(x), coil, vehicle, dynamic=True, n=50_000) for x in speeds]
    ax.plot(speeds, ratios, "k-o", label="coil dynamics")
    for x in lengths_m:
        ratios = [
            wk_ratio(kmh_to_m_s(s), coil, vehicle, magnet_length_m=x, n=50_000) for s in speeds
        ]
        ax.plot(speeds, ratios, "-s", label=f"magnet {x:g} m")
    ax.set_xlabel("speed (km/h)", fontsize=_FONT)
    ax.set_ylabel("Wk / Wk of the env's model", fontsize=_FONT)
    ax.legend(fontsize=_FONT - 1, loc="lower right")


def _payload_panel(ax, vehicle: VehicleParams, travel_m: float, lift_off_kmh: float) -> None:
    coil = eds_coil(vehicle)
    u = np.linspace(-0.3, 0.4, 71)
    weight = (vehicle.car_body_mass_kg * (1 + u) + vehicle.bogie_mass_kg) * GRAVITY_M_S2
    speed = [m_s_to_kmh(lift_off_speed_m_s(coil, w, travel_m)) for w in weight]
    ax.plot(100 * u, speed, "k-")
    ax.axhline(lift_off_kmh, color="tab:red", ls="--", label="the env's lift-off")
    ax.set_xlabel("payload (% of the car body's mass)", fontsize=_FONT)
    ax.set_ylabel(f"speed of a {travel_m * 100:g} cm sag (km/h)", fontsize=_FONT)
    ax.legend(fontsize=_FONT - 1, loc="upper left")


def figure(path: Path, lengths_m: Sequence[float] = (1.35, 2.7, 5.4)) -> Path:
    """Draw ``envelope_published.png``: the dynamic stiffness beside the quasi-static one
    (magnitude, phase), the Wk ratios against speed, the lift-off speed against payload."""
    import matplotlib.pyplot as plt

    vehicle = VehicleParams()
    coil = eds_coil(vehicle)
    fig, axes = plt.subplots(2, 2, figsize=(10.0, 7.5), dpi=100)
    _stiffness_panels(axes[0], coil, vehicle)
    _wk_panel(axes[1, 0], coil, vehicle, lengths_m)
    _payload_panel(axes[1, 1], vehicle, 0.1, 150.0)
    for ax in axes.flat:
        ax.tick_params(labelsize=_FONT)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    """Print the three tables (Markdown) and, with ``--figure``, draw the figure."""
    parser = ArgumentParser(prog="python -m capsule_env.envelope.published",
                            description=__doc__.splitlines()[0])  # fmt: skip
    parser.add_argument("--figure", type=Path, default=None, help="where to draw the PNG")
    args = parser.parse_args(argv)
    if args.figure is not None:  # before the tables, not a traceback from savefig after them
        try:
            check_writable_file(args.figure, "--figure")
        except ValueError as exc:
            parser.error(str(exc))
    vehicle = VehicleParams()
    coil = eds_coil(vehicle)
    for lines in (dynamics_table(coil, vehicle), wk_table(coil, vehicle, (1.35, 2.7, 5.4)),
                  payload_table(vehicle, (-0.3, -0.15, 0.0, 0.2, 0.4), 0.1, 150.0)):  # fmt: skip
        print("\n".join(lines), end="\n\n")
    if args.figure is not None:
        print(f"wrote {figure(args.figure)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
