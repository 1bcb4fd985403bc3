"""Plots and a short Markdown report of a campaign's output directory (``pickplace report OUT``).

:func:`write_report` reads ``OUT/results.jsonl`` and writes into ``OUT/plots/``:

* ``success_vs_params.png``: the success rate against each randomized parameter (equal-width bins, 95% Wilson
  intervals, the number of trials per bin);
* ``place_error_hist.png`` and ``cycle_time_hist.png``: histograms over the successful trials;
* ``failure_reasons.png``: failures grouped by phase, kind and reason (numbers aside);

and ``OUT/report.md``, which links them below the summary figures (with the recoveries: how many successes
needed one, the histogram of retries; and when trials failed: before the arm moved, after, or in their worker).
Matplotlib (the ``video`` extra, ``pip install 'pickplace[video]'``) is imported inside the functions and used
through its object API (``Figure`` with an Agg canvas), never pyplot.
"""

from __future__ import annotations

import json
import logging
import math
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pickplace.errors import ConfigError
from pickplace.eval.campaign import (
    CAMPAIGN_FILE,
    RESULTS_FILE,
    CampaignError,
    CampaignSummary,
    TrialRecord,
    load_records,
    summarize,
    wilson_interval,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

log = logging.getLogger(__name__)

#: The pip command that installs matplotlib.
MATPLOTLIB_HINT = "pip install 'pickplace[video]'"
#: Where the plots go, inside the campaign's output directory.
PLOTS_DIR = "plots"
REPORT_FILE = "report.md"


def _figure(width_in: float, height_in: float) -> Figure:
    """A matplotlib Figure with its own Agg canvas (no pyplot, no global state)."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise CampaignError(f"campaign plots need matplotlib, which is not installed ({exc}): "
                            f"{MATPLOTLIB_HINT}") from None
    fig = Figure(figsize=(width_in, height_in), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _display(name: str) -> tuple[str, float]:
    """Axis label and scale factor for a parameter name (lengths in mm, angles in degrees)."""
    if name.endswith("_m"):
        return f"{name[:-2]} (mm)", 1e3
    if name.endswith("_rad"):
        return f"{name[:-4]} (deg)", 180.0 / math.pi
    if name.endswith("_kg"):
        return f"{name[:-3]} (kg)", 1.0
    if name.endswith("_n"):
        return f"{name[:-2]} (N)", 1.0
    if name.endswith("_s"):
        return f"{name[:-2]} (s)", 1.0
    return name, 1.0


def varied_params(records: Sequence[TrialRecord]) -> list[str]:
    """Names of the numeric parameters that took more than one value, in the order they were recorded (the
    object drawn per trial is summarized by object instead)."""
    names: dict[str, None] = {}
    for r in records:
        names.update(dict.fromkeys(k for k, v in r.params.items() if isinstance(v, (int, float))))
    out = []
    for name in names:
        values = np.array([r.params[name] for r in records if name in r.params], dtype=float)
        if values.size and np.ptp(values) > 1e-12:
            out.append(name)
    return out


def _plot_success_vs_params(records: Sequence[TrialRecord], names: list[str], ranges: dict[str, Any],
                            path: Path) -> None:
    cols = 3
    rows = max(1, math.ceil(len(names) / cols))
    fig = _figure(4.0 * cols, 3.0 * rows)
    if not names:
        ax = fig.add_subplot()
        ax.text(0.5, 0.5, "no randomized parameter", ha="center", va="center")
        ax.set_axis_off()
    n_bins = int(np.clip(len(records) // 10, 2, 8))
    for k, name in enumerate(names):
        ax = fig.add_subplot(rows, cols, k + 1)
        label, scale = _display(name)
        rs = [r for r in records if name in r.params]
        x = np.array([r.params[name] for r in rs]) * scale
        ok = np.array([r.success for r in rs])
        span = ranges.get(name)
        lo_x, hi_x = (span[0] * scale, span[1] * scale) if isinstance(span, list) else (x.min(), x.max())
        edges = np.linspace(min(lo_x, x.min()), max(hi_x, x.max()), n_bins + 1)
        which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_bins - 1)
        centres, rates, lo, hi, counts = [], [], [], [], []
        for b in range(n_bins):
            sel = which == b
            n = int(sel.sum())
            if n == 0:
                continue
            s = int(ok[sel].sum())
            ci = wilson_interval(s, n)
            centres.append(0.5 * (edges[b] + edges[b + 1]))
            rates.append(s / n)
            lo.append(max(0.0, s / n - ci[0]))  # rounding can put the rate a hair outside its interval
            hi.append(max(0.0, ci[1] - s / n))
            counts.append(n)
        ax.errorbar(centres, rates, yerr=[lo, hi], fmt="o-", capsize=3)
        for c, n in zip(centres, counts, strict=True):
            ax.annotate(f"n={n}", (c, 0.0), textcoords="offset points", xytext=(0, 2), ha="center", fontsize=7)
        ax.set_xlim(edges[0], edges[-1])
        ax.set_ylim(-0.05, 1.08)
        ax.set_xlabel(label)
        ax.set_ylabel("success rate")
        ax.grid(alpha=0.3)
    fig.suptitle(f"Success rate against each randomized parameter ({len(records)} trials, 95% Wilson intervals)")
    fig.savefig(path)


def _plot_hist(values: np.ndarray, xlabel: str, title: str, path: Path) -> None:
    fig = _figure(6.0, 3.5)
    ax = fig.add_subplot()
    if values.size:
        ax.hist(values, bins=min(40, max(5, values.size // 5)), color="tab:blue", alpha=0.8)
        for q, style in ((50, "--"), (95, ":")):
            v = float(np.percentile(values, q))
            ax.axvline(v, color="k", linestyle=style, label=f"p{q} = {v:.3g}")
        ax.legend()
    else:
        ax.text(0.5, 0.5, "no successful trial", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("trials")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.savefig(path)


def _plot_failures(summary: CampaignSummary, path: Path) -> None:
    groups = summary.failures
    fig = _figure(9.0, max(2.5, 0.5 * len(groups) + 1.5))
    ax = fig.add_subplot()
    if groups:
        labels = ["\n".join(textwrap.wrap(f"{g.phase} · {g.kind}: {g.reason}", 70)[:3]) for g in groups]
        y = np.arange(len(groups))
        ax.barh(y, [g.count for g in groups], color="tab:red", alpha=0.8)
        ax.set_yticks(y, labels, fontsize=7)
        ax.invert_yaxis()
        ax.set_xlabel("trials")
    else:
        ax.text(0.5, 0.5, f"no failures in {summary.trials} trials", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_axis_off()
    ax.set_title(f"Failures by phase and reason ({summary.trials - summary.successes} of {summary.trials} trials)")
    fig.savefig(path)


def _pct(value: float) -> str:
    return f"{value * 100:.1f} %"


def _fmt(value: float | None, scale: float = 1.0, digits: int = 3) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    return f"{value * scale:.{digits}g}"


def summary_rows(summary: CampaignSummary) -> list[tuple[str, str]]:
    """The summary figures as (measure, value) rows, shared by the report and the CLI."""
    lo, hi = summary.success_rate_ci95
    return [
        ("trials", str(summary.trials)),
        ("successes", f"{summary.successes}/{summary.trials}"),
        ("success rate (95% Wilson interval)",
         f"{_pct(summary.success_rate)} ({_pct(lo)} – {_pct(hi)})" if summary.trials else "—"),
        ("place error xy RMS / p95 (successes)",
         f"{_fmt(summary.place_error_xy_rms_m, 1e3)} / {_fmt(summary.place_error_xy_p95_m, 1e3)} mm"),
        ("cycle time mean / p95 (successes, simulated)",
         f"{_fmt(summary.cycle_time_mean_s)} / {_fmt(summary.cycle_time_p95_s)} s"),
        ("planning time per segment median / p95",
         f"{_fmt(summary.plan_time_median_s, 1e3)} / {_fmt(summary.plan_time_p95_s, 1e3)} ms"),
        ("joint tracking error max (trajectories and holds)", f"{_fmt(summary.tracking_error_max_rad, 1e3)} mrad"),
        ("tcp tracking error max (Cartesian moves)", f"{_fmt(summary.tcp_tracking_error_max_m, 1e3)} mm"),
        ("1 ms steps of the motions over a joint speed, acceleration or torque limit (trials with any)",
         f"{summary.limit_violations} ({summary.trials_over_limits} trials); peak "
         f"{_fmt(summary.joint_limit_ratio_max)} of a limit"),
        ("tcp off its straight line max: final approach / set-down",
         f"{_fmt(summary.approach_line_deviation_max_m, 1e3)} / {_fmt(summary.place_line_deviation_max_m, 1e3)} mm"),
        ("wall time per trial (mean)", f"{_fmt(summary.wall_time_mean_s)} s"),
        ("successes that needed a recovery", f"{summary.successes_with_recovery} of {summary.successes}"),
        ("trials per number of retries (retries: trials; all but worker failures)", retries_histogram_text(summary)),
        ("failed before the arm moved (rejected in IDLE)",
         _count_share(summary.failed_before_motion, summary.failed_before_motion_rate)),
        ("failed after the arm moved (a later phase)",
         _count_share(summary.failed_after_motion, summary.failed_after_motion_rate)),
        ("worker failures (crash, timeout, exception)",
         _count_share(summary.worker_failures, summary.worker_failure_rate)),
        ("success rate of the trials not rejected in IDLE (95% Wilson)",
         _rate_ci(summary.successes, summary.trials - summary.failed_before_motion,
                  summary.success_rate_attempted_ci95)),
    ] + ([(f"{o.name}: ok / not rejected / trials (95% Wilson), place RMS, grasps",
           f"{o.successes}/{o.trials - o.rejected}/{o.trials} "
           f"{_rate_ci(o.successes, o.trials - o.rejected, o.success_rate_attempted_ci95)}, "
           f"{_fmt(o.place_error_xy_rms_m, 1e3)} mm, "
           + " ".join(f"{k} {v}" for k, v in o.grasps.items())) for o in summary.by_object]
         if len(summary.by_object) > 1 else []) + _task_rows(summary)


def _task_rows(summary: CampaignSummary) -> list[tuple[str, str]]:
    """The rows of a task campaign: task time, and failures by object (none for a campaign without either)."""
    rows = []
    if math.isfinite(summary.task_time_mean_s):
        rows.append(("task time mean / per object (successes, simulated)",
                     f"{_fmt(summary.task_time_mean_s)} / {_fmt(summary.task_time_per_object_mean_s)} s"))
    if summary.failures_by_object:
        rows.append(("failed trials by object", ", ".join(f"{k} {v}" for k, v in summary.failures_by_object.items())))
    return rows


def _rate_ci(k: int, n: int, ci: tuple[float, float]) -> str:
    """``rate (lo – hi)`` of k successes in n, or a dash."""
    if n <= 0:
        return "—"
    return f"{_pct(k / n)} ({_pct(ci[0])} – {_pct(ci[1])})"


def _count_share(count: int, rate: float) -> str:
    """``count (share of all trials)``."""
    return f"{count} ({_pct(rate)})" if math.isfinite(rate) else str(count)


def retries_histogram_text(summary: CampaignSummary) -> str:
    """The retries histogram on one line, ``retries: trials``: ``0: 47 · 1: 2 · 2: 1`` (``—`` if no episode ran)."""
    return " · ".join(f"{b.retries}: {b.trials}" for b in summary.retries_histogram) or "—"


def _markdown(out: Path, summary: CampaignSummary, plots: dict[str, Path], names: list[str]) -> str:
    def link(key: str) -> str:
        return f"![{key}]({plots[key].relative_to(out).as_posix()})"

    lines = [f"# Campaign report: `{out}`", "", "| measure | value |", "|---|---|"]
    lines += [f"| {m} | {v} |" for m, v in summary_rows(summary)]
    lines += ["", "## Success rate against each randomized parameter", "",
              f"Parameters varied: {', '.join(f'`{n}`' for n in names) or 'none'}.", "", link("success_vs_params"),
              "", "## Place error (successful trials)", "", link("place_error_hist"),
              "", "## Cycle time (successful trials)", "", link("cycle_time_hist"),
              "", "## Recoveries", "",
              f"{summary.successes_with_recovery} of the {summary.successes} successes needed at least one recovery. "
              "Trials per number of retries (recoveries used), over every trial whose episode ran "
              f"({sum(b.trials for b in summary.retries_histogram)} of {summary.trials}; worker failures have no "
              "episode):", "", "| retries | trials |", "|---|---|"]
    lines += [f"| {b.retries} | {b.trials} |" for b in summary.retries_histogram]
    lines += ["", "## Failures", "",
              f"Of {summary.trials} trials, {summary.failed_before_motion} failed before the arm moved (rejected in "
              f"IDLE), {summary.failed_after_motion} failed after it moved, and {summary.worker_failures} were "
              "worker failures (crash, timeout, exception).", "", link("failure_reasons"), ""]
    if summary.failures:
        lines += ["| phase | kind | trials | reason (numbers as #) | example |", "|---|---|---|---|---|"]
        for g in summary.failures:
            lines.append(f"| {g.phase} | {g.kind} | {g.count} | {_md_cell(g.reason)} | {_md_cell(g.example)} |")
        lines += ["", "Reproduce a failed trial alone:", "", "```"]
        lines += [f.command for f in summary.failed_trials]
        lines += ["```", ""]
    else:
        lines += [f"No failures in {summary.trials} trials.", ""]
    return "\n".join(lines)


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def write_report(out_dir: str | Path) -> list[Path]:
    """Write the campaign's plots and ``report.md``.

    Args:
        out_dir: A campaign output directory (with ``results.jsonl``).

    Returns:
        The files written: the PNGs, then ``report.md``.

    Raises:
        ConfigError: the directory holds no results.
        CampaignError: matplotlib is not installed.
    """
    out = Path(out_dir)
    records = load_records(out)
    if not records:
        raise ConfigError("out", str(out), f"holds no campaign results ({out / RESULTS_FILE} is missing or empty)")
    summary = summarize(records, out)
    names = varied_params(records)
    plots_dir = out / PLOTS_DIR
    plots_dir.mkdir(exist_ok=True)
    plots = {key: plots_dir / f"{key}.png" for key in
             ("success_vs_params", "place_error_hist", "cycle_time_hist", "failure_reasons")}
    ok = [r for r in records if r.success]
    _plot_success_vs_params(records, names, _randomization_ranges(out), plots["success_vs_params"])
    _plot_hist(_values(ok, "place_error_xy_m") * 1e3, "place error xy (mm)",
               f"Place error of the {len(ok)} successful trials", plots["place_error_hist"])
    _plot_hist(_values(ok, "cycle_time_s"), "cycle time (s, simulated)",
               f"Cycle time of the {len(ok)} successful trials", plots["cycle_time_hist"])
    _plot_failures(summary, plots["failure_reasons"])
    report = out / REPORT_FILE
    report.write_text(_markdown(out, summary, plots, names), encoding="utf-8")
    log.info("wrote %d plots and %s", len(plots), report)
    return [*plots.values(), report]


def _randomization_ranges(out: Path) -> dict[str, Any]:
    """The campaign's randomization ranges from ``campaign.json`` (empty if it is missing or unreadable)."""
    try:
        data = json.loads((out / CAMPAIGN_FILE).read_text(encoding="utf-8"))
        return dict(data.get("randomization", {}))
    except (OSError, ValueError):
        return {}


def _values(records: Sequence[TrialRecord], key: str) -> np.ndarray:
    vals: list[Any] = [r.result.get(key) for r in records]
    arr = np.array([v for v in vals if isinstance(v, (int, float))], dtype=float)
    return arr[np.isfinite(arr)]


__all__ = ["MATPLOTLIB_HINT", "PLOTS_DIR", "REPORT_FILE", "retries_histogram_text", "summary_rows", "varied_params",
           "write_report"]
