"""Where the evaluation spectra's largest low-frequency peak (about 0.6 Hz) comes from.

    python experiments/spectrum_peak.py                        # hils, seeds 1000..1009, 10 s
    python experiments/spectrum_peak.py --max-wavelength 150   # the same with the longest waves cut

Runs the passive damper on evaluate.py's episodes and prints, per spectral line up to 2 Hz,
the mean amplitude of the guideway input ``z_g`` and of the body and bogie displacements,
beside the linear plant's transmissibilities ``|H(f)|`` (``capsule_env.vehicles.modes.
frequency_response``, passive damping) and the products ``|H| z_g``: where the body and bogie
lines equal ``|H| z_g``, the peak is the guideway's own content passed through the
suspension. ``--max-wavelength`` shortens the random guideway's longest wavelength (default
500 m, the lowest input frequency ``speed / max_wavelength``: 0.45 Hz at 225 m/s).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from capsule_env.agents import make_controller

from capsule_env.evaluation.episodes import run_episodes
from capsule_env.metrics import amplitude_spectrum
from capsule_env.vehicles import VehicleParams
from capsule_env.vehicles.modes import frequency_response, natural_frequencies_hz

SIGNALS = ("guideway_elevation_m", "car_body_displacement_m", "bogie_displacement_m")


def mean_spectra(args: argparse.Namespace) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The passive run's mean amplitude spectra (m) of :data:`SIGNALS`, and their lines (Hz)."""
    passive = make_controller("passive")
    env = {**passive.env_kwargs, "setting": args.setting,
           "guideway_params": {"max_wavelength_m": args.max_wavelength}}  # fmt: skip
    roll = run_episodes(passive, env, args.episodes, args.seed, args.episode_length)
    spectra = {}
    for key in SIGNALS:
        f, a = amplitude_spectrum(roll.signals[key], roll.dt_s)
        spectra[key] = a.mean(axis=0)
    return f, spectra


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--setting", choices=["sim", "hils"], default="hils")
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=1000)
    p.add_argument("--episode-length", type=float, default=10.0, help="seconds")
    p.add_argument("--max-wavelength", type=float, default=500.0, help="m (default 500)")
    args = p.parse_args(argv)
    seeds_fit = args.episodes >= 1 and 0 <= args.seed <= 2**63 - args.episodes
    # "not (x >= bound)": a nan fails too (it passed "x < bound" and ran)
    if not (seeds_fit and args.episode_length >= 2.0 and args.max_wavelength > 2.0):
        sys.exit("spectrum_peak.py: error: --episodes >= 1, --seed in [0, 2**63 - episodes], "
                 "--episode-length >= 2 s and --max-wavelength > 2 m (the shortest "
                 f"wavelength) are required, got {args.episodes}, {args.seed}, "
                 f"{args.episode_length}, {args.max_wavelength}")  # fmt: skip
    f, s = mean_spectra(args)
    c_s = VehicleParams().passive_damping_n_s_per_m
    h = np.abs(frequency_response(f[1:], secondary_damping_n_s_per_m=c_s))
    h_body, h_bogie = np.r_[1.0, h[:, 0]], np.r_[1.0, h[:, 2]]
    zg, body, bogie = (1e3 * s[k] for k in SIGNALS)
    print(f"undamped modes {natural_frequencies_hz()[0]:.2f} / {natural_frequencies_hz()[1]:.2f}"
          f" Hz; longest guideway wave {args.max_wavelength:g} m; passive damper, "
          f"{args.setting}, seeds {args.seed}..{args.seed + args.episodes - 1}")  # fmt: skip
    for name, a in (("guideway z_g", zg), ("body", body), ("bogie", bogie)):
        k = int(np.argmax(np.where(f <= 10.0, a, 0.0)))
        print(f"largest line below 10 Hz, {name}: {f[k]:.2f} Hz, {a[k]:.2f} mm")
    print(" f Hz  z_g mm  |H_body|  body mm  |H|z_g  |H_bogie|  bogie mm  |H|z_g")
    for k in np.flatnonzero((f > 0.0) & (f <= 2.0)):
        print(f"{f[k]:5.2f} {zg[k]:7.2f} {h_body[k]:9.2f} {body[k]:8.2f} {h_body[k] * zg[k]:7.2f}"
              f" {h_bogie[k]:10.2f} {bogie[k]:9.2f} {h_bogie[k] * zg[k]:7.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
