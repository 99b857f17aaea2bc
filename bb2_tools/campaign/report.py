"""``report.html`` of a campaign: status counts, statistics of every figure, the figures against every varied
input, their distributions and the failure map (self-contained HTML, see :mod:`bb2_tools.report`; the same
images are written as PNG files into ``figures/`` beside it)."""
from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from bb2_tools.campaign.figures import figure_kinds
from bb2_tools.campaign.spec import CampaignSpec

__all__ = ["write_report", "STATUS_COLORS"]

STATUS_COLORS = {"ok": "#2f7ed8", "grounded": "#8d5524", "broached": "#e0a800", "diverged": "#d62728",
                 "error": "#6c757d"}
_MAX_FIGURES = 10
_MAX_INPUTS = 6
_DISCRETE_MAX = 12


def _floats(table: Any, name: str) -> np.ndarray:
    return np.array([math.nan if v is None else float(v) for v in table.column(name).to_pylist()], float)


def _values(table: Any, name: str) -> list[Any]:
    return table.column(name).to_pylist()


def _png(fig: Any) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return buf.getvalue()


def _is_discrete(spec: CampaignSpec, key: str, vals: list[Any]) -> bool:
    v = next(x for x in spec.vary if x.key == key)
    if v.kind in ("uniform", "normal"):
        return False
    if v.kind in ("choice", "grid", "value") or v.column_kind in ("bool", "str", "json"):
        return True
    return len(set(vals)) <= _DISCRETE_MAX


def _labels(vals: list[Any]) -> tuple[list[str], list[str]]:
    order = sorted(set(map(str, vals)), key=lambda s: (_num_or_inf(s), s))
    return [str(v) for v in vals], order


def _num_or_inf(s: str) -> float:
    try:
        return float(s)
    except ValueError:
        return math.inf


def _figure_vs_inputs(spec: CampaignSpec, table: Any, fig_name: str, inputs: list[str], status: list[str]) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    y = _floats(table, fig_name)
    n = len(inputs)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.0), squeeze=False, sharey=True)
    colors = np.array([STATUS_COLORS.get(s, "#000000") for s in status])
    for ax, key in zip(axes[0], inputs):
        vals = _values(table, key)
        if _is_discrete(spec, key, vals):
            labels, order = _labels(vals)
            pos = {lab: i for i, lab in enumerate(order)}
            x = np.array([pos[lab] for lab in labels], float)
            groups = [y[(x == i) & np.isfinite(y)] for i in range(len(order))]
            if any(len(g) for g in groups):
                ax.boxplot([g if len(g) else [np.nan] for g in groups], positions=range(len(order)), widths=0.5,
                           showfliers=False)
            jitter = (np.random.default_rng(0).random(len(x)) - 0.5) * 0.25
            ax.scatter(x + jitter, y, s=8, c=colors, alpha=0.6, linewidths=0, rasterized=True)
            ax.set_xticks(range(len(order)))
            ax.set_xticklabels([o if len(o) <= 12 else o[:11] + "…" for o in order], rotation=30, fontsize=8)
        else:
            ax.scatter(_floats(table, key), y, s=8, c=colors, alpha=0.6, linewidths=0, rasterized=True)
        ax.set_xlabel(key, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(fig_name, fontsize=9)
    fig.tight_layout()
    return _png(fig)


def _histograms(table: Any, names: list[str]) -> bytes:
    import matplotlib.pyplot as plt

    cols = min(4, len(names))
    rows = int(math.ceil(len(names) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.6 * rows), squeeze=False)
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    for ax, name in zip(axes.flat, names):
        y = _floats(table, name)
        y = y[np.isfinite(y)]
        if len(y):
            ax.hist(y, bins=min(40, max(5, int(math.sqrt(len(y))))), color="#2f7ed8", alpha=0.8)
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return _png(fig)


def _failure_map(spec: CampaignSpec, table: Any, inputs: list[str], status: list[str]) -> bytes:
    import matplotlib.pyplot as plt

    n = len(inputs)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.0), squeeze=False, sharey=True)
    st = np.array(status)
    for ax, key in zip(axes[0], inputs):
        vals = _values(table, key)
        if _is_discrete(spec, key, vals):
            labels, order = _labels(vals)
            lab = np.array(labels)
            bottom = np.zeros(len(order))
            for s, c in STATUS_COLORS.items():
                frac = np.array([np.mean(st[lab == o] == s) if np.any(lab == o) else 0.0 for o in order])
                if frac.any():
                    ax.bar(range(len(order)), frac, bottom=bottom, color=c, label=s, width=0.6)
                    bottom += frac
            ax.set_xticks(range(len(order)))
            ax.set_xticklabels([o if len(o) <= 12 else o[:11] + "…" for o in order], rotation=30, fontsize=8)
        else:
            x = _floats(table, key)
            edges = np.linspace(np.nanmin(x), np.nanmax(x), 11) if np.isfinite(x).any() else np.linspace(0, 1, 11)
            k = np.clip(np.digitize(x, edges[1:-1]), 0, 9)
            mids = 0.5 * (edges[1:] + edges[:-1])
            bottom = np.zeros(10)
            for s, c in STATUS_COLORS.items():
                frac = np.array([np.mean(st[k == j] == s) if np.any(k == j) else 0.0 for j in range(10)])
                if frac.any():
                    ax.bar(mids, frac, bottom=bottom, width=(edges[1] - edges[0]) * 0.9, color=c, label=s)
                    bottom += frac
        ax.set_xlabel(key, fontsize=9)
        ax.set_ylim(0, 1)
    axes[0][0].set_ylabel("fraction of runs")
    axes[0][-1].legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    return _png(fig)


def _stats_rows(table: Any, names: list[str]) -> list[list[str]]:
    rows = []
    for name in names:
        y = _floats(table, name)
        f = y[np.isfinite(y)]
        if len(f) == 0:
            rows.append([name, "0"] + ["-"] * 7)
            continue
        q = np.percentile(f, [5, 50, 95])
        rows.append([name, str(len(f))] + [f"{v:.4g}" for v in (f.mean(), f.std(), f.min(), *q, f.max())])
    return rows


def write_report(out_file: str | Path, spec: CampaignSpec, table: Any, meta: str = "") -> Path:
    """Write ``report.html`` from the results table; returns its path."""
    import html as _html

    import matplotlib

    matplotlib.use("Agg")
    from bb2_tools.report import html_page, image_html, table_html

    out_file = Path(out_file)
    fig_dir = out_file.parent / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)

    def saved(png: bytes, stem: str) -> bytes:
        safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in stem)
        (fig_dir / f"{safe}.png").write_bytes(png)
        return png

    status = [s or "error" for s in _values(table, "status")]
    n = len(status)
    counts = {s: status.count(s) for s in STATUS_COLORS if status.count(s)}
    sections = [("Runs", table_html(["status", "runs", "fraction"],
                                    [[s, c, f"{c / n:.1%}"] for s, c in counts.items()] + [["all", n, ""]])
                 + f"<p>{spec.n_runs} runs in the design ({spec.samples} samples x {spec.n_grid} grid points, "
                   f"{_html.escape(spec.sampling)} sampling, campaign seed {spec.seed}).</p>")]
    kinds = figure_kinds(spec.target, spec.maneuver, spec.collect)
    numeric = [k for k in spec.collect if kinds[k] == "float" and n and np.isfinite(_floats(table, k)).any()]
    numeric = numeric[:_MAX_FIGURES]
    inputs = [v.key for v in spec.vary if v.kind != "value"][:_MAX_INPUTS]   # constants tell nothing
    if numeric:
        sections.append(("Figures", table_html(["figure", "n", "mean", "std", "min", "p5", "median", "p95", "max"],
                                               _stats_rows(table, numeric))))
        sections.append(("Distributions", image_html(saved(_histograms(table, numeric), "distributions"),
                                                     "Histograms of the collected figures (finite values).")))
    if numeric and inputs:
        body = "".join(image_html(saved(_figure_vs_inputs(spec, table, f, inputs, status), f"{f}_vs_inputs"),
                                  f"{f} against each varied input (colour = status: "
                                  + ", ".join(f"{s} {c}" for s, c in STATUS_COLORS.items()) + ")")
                       for f in numeric)
        sections.append(("Figures against the varied inputs", body))
    if inputs and n:
        sections.append(("Failure map", image_html(saved(_failure_map(spec, table, inputs, status), "failure_map"),
                                                   "Fraction of runs by status against each varied input.")))
        fails = [(i, s, m) for i, s, m in zip(_values(table, "index"), status, _values(table, "message"))
                 if s != "ok"][:50]
        if fails:
            sections.append(("Failed runs (first 50)", table_html(["index", "status", "message"],
                                                                 [[i, s, m or ""] for i, s, m in fails], 2)))
    out_file.write_text(html_page(f"Campaign {spec.name}", sections, meta=meta))
    return out_file
