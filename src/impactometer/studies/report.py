"""The HTML report of a study folder: summary next to the paper's statements, figures, tables, timings."""

from __future__ import annotations

import datetime as _dt
import html
from pathlib import Path
from typing import Any

from ..errors import ParameterError
from ..tables import columns, fmt
from . import store
from .base import STUDIES, load_studies

#: marker of a report written by impactometer (an index.html without it is a user file)
MARKER = "<!-- impactometer study report -->"

#: the page checks that every figure decoded and writes the outcome into #figure-check and body[data-figures]
_CHECK_SCRIPT = """
window.addEventListener("load", function () {
  var images = Array.prototype.slice.call(document.images);
  var broken = images.filter(function (img) { return !(img.complete && img.naturalWidth > 0); });
  var out = document.getElementById("figure-check");
  if (broken.length) {
    out.textContent = "figures that failed to load: " + broken.map(function (img) {
      return img.getAttribute("src"); }).join(", ");
    out.className = "bad";
  } else {
    out.textContent = "all " + images.length + " figures loaded";
  }
  document.body.setAttribute("data-figures", (broken.length ? "broken " : "ok ") + (images.length - broken.length)
    + "/" + images.length);
});
"""

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.85em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f0f0f0; } td.text { text-align: left; }
img { max-width: 100%; border: 1px solid #ddd; }
#figure-check { color: #2a7; } #figure-check.bad { color: #c22; font-weight: bold; }
.note { color: #666; font-size: 0.9em; }
"""


def _table(rows: list[dict[str, Any]], *, limit: int = 200) -> str:
    if not rows:
        return "<p class='note'>no rows</p>"
    cols = columns(rows)
    head = "".join(f"<th>{html.escape(c)}</th>" for c in cols)
    body = []
    for row in rows[:limit]:
        cells = []
        for c in cols:
            value = row.get(c, "")
            cls = " class='text'" if isinstance(value, str) else ""
            cells.append(f"<td{cls}>{html.escape(fmt(value))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    more = f"<p class='note'>{len(rows) - limit} more rows in the CSV</p>" if len(rows) > limit else ""
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>{more}"


def collect(out: str | Path) -> list[dict[str, Any]]:
    """Results of every study run found in ``out``, in registry order (unknown ones last)."""
    load_studies()
    out = Path(out)
    order = {name: i for i, name in enumerate(STUDIES)}
    found = []
    for folder in sorted(p for p in out.iterdir() if p.is_dir()) if out.is_dir() else []:
        result = store.read_result(folder)
        if result and result.get("name") == folder.name and (out / f"{folder.name}.png").exists():
            found.append(result)
    return sorted(found, key=lambda r: order.get(r["name"], len(order)))


def summary_rows(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The report's summary: one line per statement, with the study it comes from."""
    return [{"study": r["name"], **line} for r in results for line in r.get("summary", [])]


def timing_rows(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Cases, chunks and times per study."""
    return [{"study": r["name"], "cases": r["cases"], "rows": r["rows"], "chunks": r["chunks"],
             "reused chunks": r["reused_chunks"], "workers": r["workers"],
             "wall time [s]": r["wall_time"], "compute time [s]": r["compute_time"]} for r in results]


def render(results: list[dict[str, Any]]) -> str:
    """HTML text of the report."""
    sections = []
    for r in results:
        name = html.escape(r["name"])
        figure = f" (the paper's {html.escape(r['figure'])})" if r.get("figure") else ""
        opts = r.get("options", {})
        run = html.escape(f"contact {opts.get('rig', {}).get('contact', {}).get('law')}, seed {opts.get('seed')}, "
                          f"grid {opts.get('grid') or 'default'}, settings {opts.get('params') or 'default'}")
        sections.append(
            f"<section id='{name}'><h2>{name}: {html.escape(r.get('title', ''))}{figure}</h2>"
            f"<p><img src='{name}.png' alt='figure of study {name}'></p>"
            f"<p class='note'>{r['cases']} cases, {r['rows']} rows; full table: <a href='{name}.csv'>{name}.csv"
            f"</a>; {run}; wall time {r['wall_time']:.1f} s, compute time {r['compute_time']:.1f} s</p>"
            f"{_table(r.get('aggregate', []))}</section>")
    options = results[0]["options"] if results else {}
    rig = options.get("rig", {})
    contact = rig.get("contact", {})
    grid = options.get("grid")
    law_parameters = ", ".join(f"{k} {v:g}" for k, v in contact.items() if k != "law" and v is not None)
    setup = (f"Stand {rig.get('name', '?')}, contact {contact.get('law')} ({law_parameters}); "
             f"root seed {options.get('seed')}; "
             f"{'each study' + chr(39) + 's default grid' if grid is None else f'{grid} values per grid axis'}; "
             f"{options.get('seeds')} noise realisation(s) per case; base noise {options.get('noise', 0) * 100:g} % "
             f"of RMS at {options.get('sample_rate', 0) / 1e3:g} kHz.") if options else ""
    setup = html.escape(setup)
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return f"""<!DOCTYPE html>
{MARKER}
<html lang="en"><head><meta charset="utf-8"><title>impactometer studies</title>
<style>{_STYLE}</style></head>
<body data-figures="pending">
<h1>impactometer studies</h1>
<p class="note">Written {stamp}. {setup}</p>
<p id="figure-check">checking figures…</p>
<h2>Summary: our numbers next to the paper's</h2>
{_table(summary_rows(results))}
<h2>Run</h2>
{_table(timing_rows(results))}
{''.join(sections)}
<script>{_CHECK_SCRIPT}</script>
</body></html>
"""


def check_target(out: str | Path, *, force: bool = False) -> Path:
    """``out/index.html``, refused if it exists and was not written by impactometer (unless ``force``)."""
    path = Path(out) / "index.html"
    if path.exists() and not force:
        try:
            ours = MARKER in path.read_text(encoding="utf-8", errors="replace")[:500]
        except OSError:
            ours = False
        if not ours:
            raise ParameterError(f"--out: {str(path)!r} exists and was not written by impactometer; pass --overwrite "
                                 f"to overwrite it")
    return path


def write_report(out: str | Path, *, force: bool = False) -> Path:
    """Write ``out/index.html`` from every study run found in ``out``; a foreign index.html needs ``force``."""
    out = Path(out)
    if not out.is_dir():
        raise ParameterError(f"--out: {str(out)!r} is not a folder of study runs")
    with store.locked(out):
        return store.atomic_write(check_target(out, force=force), render(collect(out)))


def markdown(out: str | Path) -> str:
    """The run table and the summary of the study runs in ``out`` as Markdown tables (for READMEs)."""
    results = collect(out)

    def table(rows: list[dict[str, Any]]) -> str:
        if not rows:
            return "(no study runs found)\n"
        cols = columns(rows)
        lines = ["| " + " | ".join(cols) + " |", "| " + " | ".join("---" for _ in cols) + " |"]
        lines += ["| " + " | ".join(fmt(r.get(c, "")).replace("|", "/") for c in cols) + " |" for r in rows]
        return "\n".join(lines) + "\n"

    timing = timing_rows(results)
    total = {"study": "total", "cases": sum(r["cases"] for r in timing), "rows": sum(r["rows"] for r in timing),
             "chunks": sum(r["chunks"] for r in timing), "reused chunks": sum(r["reused chunks"] for r in timing),
             "workers": "", "wall time [s]": sum(r["wall time [s]"] for r in timing),
             "compute time [s]": sum(r["compute time [s]"] for r in timing)} if timing else None
    return table(timing + ([total] if total else [])) + "\n" + table(summary_rows(results))
