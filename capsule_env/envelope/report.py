"""The envelope page's tables and figures, generated from ``experiments/envelope.py``'s JSON.

``python -m capsule_env.envelope.report docs/envelope.md`` rewrites the block between the
page's ``<!-- generated: envelope -->`` markers from ``docs/figures/envelope.json`` (a test
checks the page is in sync); ``experiments/envelope.py`` does the same at the end of a run and
draws the figures (:func:`figures`): the Wk-weighted RMS car-body acceleration against speed
per controller (EDS solid, fixed levitation dashed) and the car-body acceleration's PSD with and
without the tube's spans at 810 km/h.

The JSON (``points``: key -> ``sweep``, ``label``, ``value``, ``env_kwargs``, ``controllers``:
name -> ``wk_rms_body_acc_m_s2``, ``wk_std_m_s2``, ... or ``skipped`` with the reason) is the
only input: nothing here knows the grid.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from capsule_env.common.safe_io import atomic_write_text
from capsule_env.common.units import kmh_to_m_s

__all__ = ["tables", "figures", "sync_page", "BEGIN", "END"]

BEGIN, END = "<!-- generated: envelope -->", "<!-- end generated: envelope -->"
SWEEP_TITLES = {
    "speed": "Speed",
    "payload": "Payload (EDS, 810 km/h)",
    "spans": "Tube spans (EDS, 810 km/h)",
    "trip": "The trip task",
}
WK = "wk_rms_body_acc_m_s2"


def _points(data: dict, sweep: str, levitation: str | None = None) -> list[tuple[str, dict]]:
    """The points of ``sweep`` (and of ``levitation`` for the speed sweep), in value order."""
    rows = [(k, p) for k, p in data["points"].items() if p["sweep"] == sweep]
    if levitation is not None:
        rows = [(k, p) for k, p in rows if p["env_kwargs"].get("levitation") == levitation]
    return sorted(rows, key=lambda kp: kp[1]["value"]) if sweep == "speed" else rows


def _names(points: list[tuple[str, dict]]) -> list[str]:
    """Every controller of ``points`` in first-seen order, the oracle last."""
    names: list[str] = []
    for _, p in points:
        names += [n for n in p["controllers"] if n not in names]
    return [n for n in names if n != "oracle"] + (["oracle"] if "oracle" in names else [])


def _ran_anywhere(points: list[tuple[str, dict]], notes: list[str]) -> list[str]:
    """The controllers of ``points`` (:func:`_names`) with a result at one of them at least;
    for each of the others one note per reason, naming the points that gave it (e.g. a law
    made for the trip task at the constant-speed points; the reason names each point's own
    value, so points of a sweep have reasons of their own)."""
    names = _names(points)
    ran = [n for n in names if any(WK in p["controllers"].get(n, {}) for _, p in points)]
    for name in names:
        if name in ran:
            continue
        by_reason: dict[str, list[str]] = {}
        for key, p in points:
            if name in p["controllers"]:
                reason = p["controllers"][name].get("skipped", "not run")
                by_reason.setdefault(reason, []).append(f"`{key}`")
        notes += [f"`{name}` at {', '.join(keys)}: {reason}" for reason, keys in by_reason.items()]
    return ran


def _best(p: dict) -> str | None:
    """The controller (not the oracle) of the lowest Wk at a point."""
    run = {n: e[WK] for n, e in p["controllers"].items() if WK in e and n != "oracle"}
    return min(run, key=run.__getitem__) if run else None


def _headroom(p: dict, best: str | None) -> str:
    """``(passive - best) / (passive - oracle)`` at a point with the oracle, else a dash."""
    wk = {n: e.get(WK) for n, e in p["controllers"].items()}
    if best is None or wk.get("oracle") is None or wk.get("passive") is None:
        return "–"
    return f"{(wk['passive'] - wk[best]) / (wk['passive'] - wk['oracle']):.2f}"


def _column_title(p: dict) -> str:
    sweep, value = p["sweep"], p["value"]
    if sweep == "speed":
        return f"{value:g}"
    if sweep == "payload":
        return f"{100 * value:+.0f} %"
    return p["label"].replace("simply supported", "s.s.").replace("continuous ", "")


def _table(points: list[tuple[str, dict]], notes: list[str]) -> list[str]:
    """Wk (m/s^2) per controller (rows) and point (columns), the best law bold, the skipped
    cells a dash with their reason in ``notes``; then the best law's ratio to passive, its
    share of the oracle's headroom (where the oracle ran) and the mean over the episodes of
    the env's guideway scale (where the JSON has it)."""
    names, best = _ran_anywhere(points, notes), [_best(p) for _, p in points]
    lines = ["| controller | " + " | ".join(_column_title(p) for _, p in points) + " |",
             "| --- |" + " ---: |" * len(points)]  # fmt: skip
    for name in names:
        cells = []
        for (key, p), b in zip(points, best):
            e = p["controllers"].get(name)
            if e is None or WK not in e:
                cells.append("–")
                reason = f"`{name}` at `{key}`: {e['skipped']}" if e is not None else None
                if reason is not None and reason not in notes:
                    notes.append(reason)
                continue
            text = f"{e[WK]:.4f}"
            cells.append(f"**{text}**" if name == b else text)
        lines.append(f"| `{name}` | " + " | ".join(cells) + " |")
    ratios = []
    for (_, p), b in zip(points, best):
        passive = p["controllers"].get("passive", {}).get(WK)
        ratios.append(f"{p['controllers'][b][WK] / passive:.3f}" if b and passive else "–")
    lines.append("| best / passive | " + " | ".join(ratios) + " |")
    if any("oracle" in p["controllers"] for _, p in points):
        lines.append("| headroom closed | " + " | ".join(_headroom(p, b) for (_, p), b in
                                                          zip(points, best)) + " |")  # fmt: skip
    gains = [p.get("guideway_gain") for _, p in points]
    if any(gains):
        lines.append("| guideway scale | " + " | ".join(
            f"{sum(g) / len(g):.3f}" if g else "–" for g in gains) + " |")  # fmt: skip
    return lines


def tables(data: dict) -> str:
    """The page's generated block: the run's configuration and one table per sweep (the speed
    sweep one per levitation model)."""
    c = data["config"]
    lines = [f"Run: {c['episodes']} episodes of {c['episode_length_s']:g} s per point (seeds "
             f"{c['seed']}..{c['seed'] + c['episodes'] - 1}, guideway bank "
             f"{c['guideway_seed']}), setting `{c['setting']}`, measured signals; "
             f"{data.get('runtime_s', 0.0) / 60:.1f} min of computation in all. Wk-weighted "
             "RMS car-body acceleration (m/s²), mean over the episodes; bold: the lowest of "
             "the controllers (the oracle, a clairvoyant local search, aside: a reference, not "
             "a limit); `best / passive`: that lowest over the passive damper's; `headroom "
             "closed`, where the oracle ran: `(passive - best) / (passive - oracle)`; `guideway "
             "scale`: the mean factor the env applied to the "
             "random profile's window to bring its peak to 8 mm.", ""]  # fmt: skip
    notes: list[str] = []
    groups = [("speed", "eds", "Speed, EDS levitation (km/h)"),
              ("speed", "fixed", "Speed, fixed levitation stiffness (km/h)"),
              ("payload", None, SWEEP_TITLES["payload"]), ("spans", None, SWEEP_TITLES["spans"]),
              ("trip", None, SWEEP_TITLES["trip"])]  # fmt: skip
    for sweep, lev, title in groups:
        points = _points(data, sweep, lev)
        if points:
            lines += [f"**{title}**", "", *_table(points, notes), ""]
    if notes:
        lines += ["Not run:", "", *(f"- {n}" for n in notes), ""]
    return "\n".join(lines).rstrip() + "\n"


def sync_page(page: Path, results_json: Path) -> bool:
    """Rewrite the generated block of ``page`` from ``results_json``; True when it changed."""
    text = page.read_text()
    if BEGIN not in text or END not in text:
        raise ValueError(f"{page} has no {BEGIN} ... {END} block")
    head, _, rest = text.partition(BEGIN)
    _, _, tail = rest.partition(END)
    new = f"{head}{BEGIN}\n\n{tables(json.loads(Path(results_json).read_text()))}\n{END}{tail}"
    if new != text:
        atomic_write_text(page, new)  # a Ctrl-C or full disk: the page as it was
    return new != text


# ----------------------------------------------------------------------------- figures
def figures(data: dict, folder: Path) -> list[Path]:
    """``envelope_speed.png`` (when the JSON has the speed sweep) and ``envelope_span_psd.png``
    (when it has the PSDs at 810 km/h without and with 30 m continuous spans) in ``folder``,
    at the docs' width and fonts (:data:`capsule_env.plots.DOC_STYLE`)."""
    from capsule_env.plots import DOC_STYLE, _pyplot

    plt, written = _pyplot(), []
    folder = Path(folder)
    with plt.rc_context(DOC_STYLE):
        if _points(data, "speed"):
            written.append(_speed_figure(plt, data, folder / "envelope_speed.png"))
        pairs = _psd_pairs(data)
        if pairs:
            written.append(_psd_figure(plt, pairs, folder / "envelope_span_psd.png"))
    return written


def _speed_figure(plt: Any, data: dict, path: Path) -> Path:
    from capsule_env.plots import DOC_WIDTH_IN

    names = _ran_anywhere(_points(data, "speed"), [])
    rows = -(-len(names) // 4)
    fig, (ax, rel) = plt.subplots(1, 2, figsize=(DOC_WIDTH_IN, 3.7 + 0.2 * rows),
                                  layout="constrained")  # fmt: skip
    colours = plt.get_cmap("tab10")
    for k, name in enumerate(names):
        for lev, style in (("eds", "-"), ("fixed", "--")):
            xs, ys, rs = [], [], []
            for _, p in _points(data, "speed", lev):
                e, passive = p["controllers"].get(name, {}), p["controllers"].get("passive", {})
                if WK in e:
                    xs.append(p["value"])
                    ys.append(e[WK])
                    rs.append(e[WK] / passive[WK] if WK in passive else float("nan"))
            marker = "*" if name == "oracle" else "o"
            kw = {"color": "black" if name == "oracle" else colours(k % 10), "marker": marker,
                  "ms": 9 if name == "oracle" else 3, "ls": style, "lw": 1.2}  # fmt: skip
            label = f"{name}" if lev == "eds" else None
            ax.plot(xs, ys, label=label, **kw)
            rel.plot(xs, rs, **kw)
    ax.set(xlabel="speed (km/h)", ylabel="Wk-weighted RMS body acceleration (m/s²)",
           title="Wk against speed")  # fmt: skip
    rel.set(xlabel="speed (km/h)", ylabel="Wk / Wk of the passive damper",
            title="relative to the passive damper")  # fmt: skip
    for a in (ax, rel):
        a.grid(alpha=0.3)
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=4)
    fig.suptitle("The speed sweep: EDS levitation solid, fixed levitation dashed")
    return _save(plt, fig, path)


#: The PSD figure's rows: (point without spans, point with 30 m spans, the row's title).
PSD_PAIRS = (
    ("speed/eds/810", "spans/continuous/30m/L3000", "random profile at 8 mm peak (the env)"),
    ("spans/unscaled/none", "spans/unscaled/continuous/30m/L3000", "unscaled profile"),
)
PSD_CONTROLLERS = ("passive", "lqr-clipped-biexp-meas")


def _psd_pairs(data: dict) -> list[tuple[dict, dict, str]]:
    """The rows of :data:`PSD_PAIRS` whose two points hold the passive damper's PSD."""
    pairs = []
    for base_key, spans_key, title in PSD_PAIRS:
        base, spans = data["points"].get(base_key), data["points"].get(spans_key)
        if all(p is not None and "psd_m2_s4_per_hz" in p["controllers"].get("passive", {})
               for p in (base, spans)):  # fmt: skip
            pairs.append((base, spans, title))
    return pairs


def _psd_figure(plt: Any, pairs: list[tuple[dict, dict, str]], path: Path) -> Path:
    from capsule_env.plots import DOC_WIDTH_IN

    names = [n for n in PSD_CONTROLLERS if all(n in p[1]["controllers"] for p in pairs)]
    fig, axes = plt.subplots(len(pairs), len(names), figsize=(DOC_WIDTH_IN, 0.8 + 3.1 * len(pairs)),
                             squeeze=False, layout="constrained")  # fmt: skip
    lines = set()
    for row, (base, spans, title) in zip(axes, pairs):
        span_m = spans["env_kwargs"]["span_params"]["span_m"]
        f_span = kmh_to_m_s(spans["env_kwargs"]["speed_kmh"]) / span_m
        lines.add(f"v/L = {f_span:.2f} Hz")
        for ax, name in zip(row, names):
            for p, label, colour in ((base, "no spans", "tab:blue"),
                                     (spans, f"{span_m:g} m spans", "tab:red")):  # fmt: skip
                e = p["controllers"][name]
                ax.semilogy(e["psd_frequency_hz"], e["psd_m2_s4_per_hz"], color=colour,
                            label=label)  # fmt: skip
            top = max(base["controllers"][name]["psd_frequency_hz"])
            for k in range(1, int(top // f_span) + 1):
                ax.axvline(k * f_span, color="grey", ls=":", lw=1)
            ax.set(xlabel="frequency (Hz)", ylabel="body acc. PSD ((m/s²)²/Hz)",
                   title=f"{name}\n{title}")  # fmt: skip
            ax.grid(alpha=0.3, which="both")
            ax.legend()
    fig.suptitle(
        f"EDS, 810 km/h; dotted: the span frequency's multiples k v/L, {', '.join(sorted(lines))}"
    )
    return _save(plt, fig, path)


def _save(plt: Any, fig: Any, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """``python -m capsule_env.envelope.report [docs/envelope.md]``: rewrite the page's block
    from ``figures/envelope.json`` beside it; a missing or unreadable file: one line, status 2."""
    args = sys.argv[1:] if argv is None else argv
    usage = "usage: python -m capsule_env.envelope.report [PAGE.md]"
    if args[:1] in (["-h"], ["--help"]):
        print(usage)
        return 0
    if len(args) > 1 or (args and args[0].startswith("-")):
        print(usage, file=sys.stderr)
        return 2
    target = Path(args[0]) if args else Path("docs/envelope.md")
    try:
        changed = sync_page(target, target.parent / "figures" / "envelope.json")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"python -m capsule_env.envelope.report: error: {target}: {exc}", file=sys.stderr)
        return 2
    print(("updated " if changed else "unchanged ") + str(target))
    return 0


if __name__ == "__main__":
    sys.exit(main())
