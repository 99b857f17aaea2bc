"""One self-contained HTML report of analysed bags: figures as base64 PNG, tables, warnings.

The file references nothing outside itself (no scripts, no stylesheets, no remote images): every
image is a ``data:image/png;base64,...`` URI and the style sheet is inline, so it can be mailed or
attached to a ticket as is.  :func:`html_page` is the generic builder; :func:`write_analysis_report`
lays out the figures of one or two :class:`bb2_tools.analysis.Analysis` runs.
"""
from __future__ import annotations

import base64
import html
import math
import time
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from bb2_tools.analysis import Analysis, compare, format_figure

__all__ = ["png_data_uri", "image_html", "table_html", "html_page", "write_analysis_report", "PNG_SIGNATURE"]

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

STYLE = """
body { font-family: "DejaVu Sans", "Liberation Sans", Arial, sans-serif; margin: 24px 32px; color: #1d2733;
       background: #ffffff; max-width: 1300px; }
h1 { font-size: 22px; margin-bottom: 4px; }
h2 { font-size: 17px; margin-top: 28px; border-bottom: 2px solid #d0d7e2; padding-bottom: 3px; }
p.meta { color: #55606e; font-size: 13px; margin-top: 0; }
table { border-collapse: collapse; font-size: 13px; margin: 8px 0 16px 0; }
th, td { border: 1px solid #c9d1dc; padding: 3px 9px; text-align: right; }
th { background: #e8eef6; }
td.name, th.name { text-align: left; font-family: "DejaVu Sans Mono", monospace; }
tr:nth-child(even) td { background: #f6f8fb; }
div.warn { background: #fff4d6; border-left: 5px solid #e0a800; padding: 6px 12px; margin: 6px 0;
           font-size: 13px; }
div.ok { background: #e7f6ea; border-left: 5px solid #2f9e44; padding: 6px 12px; font-size: 13px; }
figure { margin: 10px 0 22px 0; }
figure img { max-width: 100%; border: 1px solid #d7dde6; }
figcaption { font-size: 12px; color: #55606e; }
div.grid { display: flex; flex-wrap: wrap; gap: 16px; }
div.grid figure { flex: 1 1 600px; }
"""


def png_data_uri(png: bytes | str | Path) -> str:
    """``data:image/png;base64,...`` of PNG bytes or a PNG file; rejects non-PNG data."""
    data = png if isinstance(png, bytes) else Path(png).read_bytes()
    if not data.startswith(PNG_SIGNATURE):
        raise ValueError(f"not a PNG image: {png if not isinstance(png, bytes) else '<bytes>'}")
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def image_html(png: bytes | str | Path, caption: str, alt: str | None = None) -> str:
    return (f'<figure><img src="{png_data_uri(png)}" alt="{html.escape(alt or caption)}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def table_html(header: Sequence[str], rows: Iterable[Sequence[Any]], name_columns: int = 1) -> str:
    """An HTML table; the first ``name_columns`` columns are left-aligned names."""
    def cell(tag: str, j: int, v: Any) -> str:
        cls = ' class="name"' if j < name_columns else ""
        return f"<{tag}{cls}>{html.escape(str(v))}</{tag}>"

    head = "<tr>" + "".join(cell("th", j, h) for j, h in enumerate(header)) + "</tr>"
    body = "".join("<tr>" + "".join(cell("td", j, v) for j, v in enumerate(r)) + "</tr>" for r in rows)
    return f"<table>{head}{body}</table>"


def html_page(title: str, sections: Sequence[tuple[str, str]], meta: str = "") -> str:
    """A complete HTML document: ``sections`` are (heading, inner HTML)."""
    parts = [f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
             f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>",
             f"<h1>{html.escape(title)}</h1>"]
    if meta:
        parts.append(f'<p class="meta">{html.escape(meta)}</p>')
    for heading, inner in sections:
        parts.append(f"<h2>{html.escape(heading)}</h2>{inner}")
    parts.append("</body></html>\n")
    return "".join(parts)


FIGURE_CAPTIONS = {
    "track_3d": "Path (red dashed) vs track of the CG, native earth frame (z up).",
    "plan_view": "Plan view: path vs track (terrain contours when the mission's terrain is known).",
    "path_errors": "Vertical and horizontal path errors (solid: the stack's own p_T; dashed: from the closest "
                   "path point) and ground clearance.",
    "commands": "deltaV / deltaH commands of the autopilot and the five actual plane angles.",
    "rate_commands": "Path-following pitch/yaw rate commands q_c, r_c (native).",
    "speed_depth_fpa": "Speed, depth (with the sea floor under the CG) and flight-path angle / pitch.",
    "maneuver": "Maneuver plot (bb2_sim.plots) with its figures.",
}


KEY_FIGURES = ("mission_time_s", "rms_vertical_m", "max_vertical_m", "rms_horizontal_m", "max_horizontal_m",
               "rms_vertical_closest_m", "rms_horizontal_closest_m", "min_clearance_m", "min_hull_clearance_m",
               "min_altitude_m", "dV_max_abs_rad", "dH_max_abs_rad", "planes_any_saturated_fraction",
               "real_time_factor")


def _figures_table(analyses: Sequence[Analysis], names: Sequence[str]) -> str:
    if len(analyses) == 1:
        f = analyses[0].named_figures
        rows = [list(format_figure(k, f[k])) for k in names if k in f]
        return table_html(["figure", "value", "unit"], rows)
    diffs = {k: (va, vb, d) for k, va, vb, d in compare(analyses[0], analyses[1])}
    rows = []
    for k in names:
        va, vb, d = diffs[k]
        lab, ta, unit = format_figure(k, va)
        rows.append([lab, ta, format_figure(k, vb)[1], format_figure(k, d)[1], unit])
    return table_html(["figure", f"A: {analyses[0].label}", f"B: {analyses[1].label}", "B - A", "unit"], rows)


def _topics_table(analyses: Sequence[Analysis]) -> str:
    names = sorted({t for a in analyses for t in a.run.topics})
    header = ["topic", "type"] + [f"messages ({a.label})" for a in analyses]
    rows = []
    for n in names:
        typ = next((a.run.topics[n] for a in analyses if n in a.run.topics), "")
        rows.append([n, typ] + [a.run.counts.get(n, "-") if n in a.run.topics else "-" for a in analyses])
    return table_html(header, rows, name_columns=2)


def write_analysis_report(analyses: Sequence[Analysis], files: Mapping[str, Path], out_file: str | Path) -> Path:
    """Write the HTML report of one or two analyses with the PNG ``files`` embedded; returns the file."""
    out = Path(out_file)
    sections: list[tuple[str, str]] = []
    summary_rows = []
    for a in analyses:
        r = a.run
        summary_rows.append([a.label, str(r.source), r.state_source, r.path_source or "none",
                             getattr(a.mission, "name", "-") or "-", a.maneuver or "-",
                             "TRUNCATED" if r.truncated else "complete", sum(r.counts.values())])
    sections.append(("Runs", table_html(["label", "bag", "trajectory from", "path from", "mission", "maneuver",
                                         "file", "messages"], summary_rows, name_columns=2)))
    warn_html = []
    for a in analyses:
        if a.run.truncated:
            warn_html.append(f'<div class="warn"><b>{html.escape(a.label)}: truncated bag</b> -- read up to the '
                             f"last complete chunk ({html.escape(a.run.problem or 'no summary')}).</div>")
        for w in a.warnings:
            if a.run.truncated and w.startswith("the bag is truncated"):
                continue
            warn_html.append(f'<div class="warn">{html.escape(a.label)}: {html.escape(w)}</div>')
    sections.append(("Warnings", "".join(warn_html) or '<div class="ok">none</div>'))

    named = [a.named_figures for a in analyses]
    key = [k for k in KEY_FIGURES if any(k in f for f in named)]
    sections.append(("Key figures", _figures_table(analyses, key)))
    plots = [image_html(files[name], FIGURE_CAPTIONS.get(name, name), alt=name)
             for name in ("path_errors", "track_3d", "plan_view", "commands", "rate_commands", "speed_depth_fpa",
                          "maneuver") if name in files]
    sections.append(("Plots", '<div class="grid">' + "".join(plots) + "</div>"))
    for a in analyses:
        if a.maneuver_figures is not None:
            rows = [[lab, _fmt_any(v), unit] for lab, v, unit in a.maneuver_figures.as_rows()]
            sections.append((f"Maneuver figures ({a.maneuver}, {a.label})",
                             table_html(["figure", "value", "unit"], rows)))
    all_names = list(dict.fromkeys(k for f in named for k in f))
    sections.append(("All figures" if len(analyses) == 1 else "All figures (A vs B)",
                     _figures_table(analyses, all_names)))
    sections.append(("Topics", _topics_table(analyses)))
    title = "BB2 run analysis" if len(analyses) == 1 else "BB2 run comparison"
    meta = (" vs ".join(a.label for a in analyses) + f" -- bb2-analyze, {time.strftime('%Y-%m-%d %H:%M:%S')}")
    out.write_text(html_page(title, sections, meta), encoding="utf-8")
    return out


def _fmt_any(v: Any) -> str:
    if isinstance(v, tuple):
        return ", ".join(_fmt_any(x) for x in v)
    if isinstance(v, float):
        return "n/a" if not math.isfinite(v) else f"{v:.4g}"
    return str(v)
