"""What ``evaluate.py`` prints below its tables for a reader: the key to the controller names
and the note on on-off Skyhook's two figures.

The key has one line per controller row, for a reader who knows suspension control but not
this package's names (``sh-add-meas``, ``hybrid-biexp-meas``, ...): the law, the way it drives
the damper, and the signals it reads. What a row reads is taken from the results (the
observation set the controller declared, and whether it previews the guideway), not from its
name, so a controller of your own gets a correct "reads" part too. The note is written from
the figures of the run, and only when they show it.
"""

from __future__ import annotations

from collections.abc import Sequence

#: What each built-in row is (``capsule_env.agents.classical_controllers()``, the oracle and the
#: shipped policies), short enough for one line. Force laws request a force through the named
#: inverse model (force mode); two-state laws switch the coil between 0 A and a tuned ``i_on``.
DESCRIPTIONS = {
    "passive": "linear passive damper, c_s = 15 kN s/m (the reference)",
    "mr-0A": "MR damper held at 0 A (softest)",
    "mr-imax": "MR damper held at i_max = 1.5 A (hardest)",
    "skyhook-csdc": "paper's on-off Skyhook, c_max 70 kN s/m, Bouc-Wen inverse (CSDC)",
    "skyhook-biexp": "paper's on-off Skyhook, c_max 70 kN s/m, Bi-exponential inverse",
    "skyhook-tanh": "paper's on-off Skyhook, c_max 70 kN s/m, tanh inverse",
    "skyhook-cont-biexp": "continuous Skyhook F = c_sky z_c', Bi-exponential inverse",
    "skyhook-cont-csdc": "continuous Skyhook F = c_sky z_c', Bouc-Wen inverse (CSDC)",
    "skyhook-cont-tanh": "continuous Skyhook F = c_sky z_c', tanh inverse",
    "hybrid-biexp": "hybrid Skyhook-groundhook, Bi-exponential inverse",
    "lqr-clipped-biexp": "clipped-optimal LQR (stroke, gap, velocities), Bi-exponential inverse",
    "skyhook-meas": "on-off Skyhook, two-state (i_on or 0 A)",
    "skyhook-cont-biexp-meas": "continuous Skyhook on the velocity estimate, Bi-exp. inverse",
    "hybrid-biexp-meas": "hybrid Skyhook-groundhook on the velocity estimates, Bi-exp. inverse",
    "add-meas": "acceleration-driven damper (ADD), two-state (i_on or 0 A)",
    "sh-add-meas": "mixed Skyhook-ADD, two-state: Skyhook below a crossover frequency, ADD above",
    "lqr-clipped-biexp-meas": "clipped-optimal LQR on LVDT, gap sensor, velocity estimates, "
    "Bi-exp. inverse",
    "lqr-sched-biexp-meas": "gain-scheduled clipped LQR: gains designed at the EDS levitation "
    "of each speed, interpolated at the measured speed, Bi-exp. inverse",
    "preview-lq-biexp-meas": "LQ optimal preview: LQR with the guideway 1 s ahead, Bi-exp. inverse",
    "preview-lq-biexp": "LQ optimal preview: LQR with the guideway 1 s ahead, Bi-exp. inverse",
    "mpc-biexp-meas": "semi-active MPC: 50 ms plan inside the damper's band, on the LQR's "
    "signals, Bi-exp. inverse",
    "mpc-biexp": "semi-active MPC: 50 ms plan inside the damper's band, Bi-exp. inverse",
    "preview-mpc-biexp-meas": "semi-active MPC with the guideway 1 s ahead, Bi-exp. inverse",
    "preview-mpc-biexp": "semi-active MPC with the guideway 1 s ahead, Bi-exp. inverse",
    "oracle": "clairvoyant search: current searched knowing the guideway, no noise or delay",
}

#: What a row reads, by its observation set (``entry["observation"]`` of the results).
READS = {
    "none": "nothing",
    "measured": "on-board sensors",
    "sensors": "accelerometers, stroke, stroke rate",
    "full_state": "ideal sensors (true states)",
    "oracle": "the whole guideway",
}

#: The description of a row that names a learned policy (listed under "policies").
POLICY = "learned policy (SB3 model, its file under 'policies')"
#: The description of a controller this module does not know (one built in Python).
UNKNOWN = "a controller given in Python"
#: The key's first line.
KEY_TITLE = (
    "Key (gains tuned on the training bank unless stated; force laws request a force through "
    "the named inverse model, two-state laws switch between 0 A and a tuned i_on):"
)


def reads(entry: dict) -> str:
    """What a controller reads, from its results entry (``observation``, ``preview``)."""
    observation = entry.get("observation", "unknown")
    text = READS.get(observation, f"the {observation!r} observation set")
    if entry.get("preview") and observation != "oracle":
        text += " + the guideway ahead"
    return text


def key_lines(controllers: dict[str, dict], policies: dict[str, str], width: int) -> list[str]:
    """The key: a title, then one line per controller of ``controllers`` (name -> results
    entry, in table order), ``name`` padded to ``width``, what it is and what it reads."""
    lines = [KEY_TITLE]
    for name, entry in controllers.items():
        what = POLICY if name in policies else DESCRIPTIONS.get(name, UNKNOWN)
        lines.append(f"  {name:<{width}}{what} [reads: {reads(entry)}]")
    return lines


#: The on-off (two-state) Skyhook laws: the paper's three and the measured two-state one.
ON_OFF_SKYHOOKS = ("skyhook-csdc", "skyhook-biexp", "skyhook-tanh", "skyhook-meas")


def on_off_note(controllers: dict[str, dict]) -> str | None:
    """One line saying which on-off Skyhook rows raise the body's first-mode VRE while their
    Wk-weighted acceleration is worse than the passive damper's (None when no row does): the
    two figures measure different things, and on-off switching injects high-frequency force."""
    if "passive" not in controllers:
        return None
    wk_passive = controllers["passive"]["wk_rms_body_acc_m_s2"]
    rows = [
        (name, m["vre_pct"]["body_mode1"], m["wk_rms_body_acc_m_s2"])
        for name, m in controllers.items()
        if name in ON_OFF_SKYHOOKS
        and m.get("vre_pct", {}).get("body_mode1", 0.0) > 0.0
        and m["wk_rms_body_acc_m_s2"] > wk_passive
    ]
    if not rows:
        return None
    figures = ", ".join(f"{name} {v:.1f} % / {w:.4f}" for name, v, w in rows)
    return (
        "Note: on-off Skyhook raises the body's first-mode VRE but worsens comfort (Wk above "
        f"passive's {wk_passive:.4f} m/s^2): {figures} (VRE / Wk m/s^2); its switching injects "
        "high-frequency force, which the displacement peak does not see."
    )


def column_footer(headroom: bool, fixed_gains: Sequence[str]) -> str:
    """The columns' meanings below the tables (``headroom``'s only when it is printed;
    ``fixed_gains``: the rows whose gains are the paper's, not tuned)."""
    text = (
        "Columns: VRE (%): (P_passive - P_control)/P_passive*100 at the displacement-spectrum "
        "peak in the band (paper eq. 16); Wk / rms: ISO 2631-1 Wk-weighted and plain RMS "
        "car-body acceleration (m/s^2); stroke: max |x| (mm); I: mean coil current (A); trk rel: "
        "force-tracking error rms(F - F_d)/rms(F_d) (a ratio); Wz: Sperling ride index (RMS "
        "form); N_v: EN 12299 mean comfort, vertical term 6 a_ZP95 (Wb). Gains: tuned on the "
        "training guideway bank (agents/controllers/tuned_gains.json, python -m capsule_env.agents.controllers.tuning), "
        "except " + ", ".join(fixed_gains) + " (the paper's reconstructed c_max = 7e4 N s/m). "
        "'+preview' groups read the surveyed guideway ahead (env option preview_points)."
    )
    if headroom:
        text += (
            " headroom: the share of the Wk gap passive -> oracle a controller closes (the "
            "oracle: capsule_env.oracle, the applied current searched knowing the whole "
            "guideway, no noise or delay)."
        )
    return text
