"""A sweep's results: Parquet table and an HTML report (Jinja2, inline SVG, no JavaScript).

The report shows, per swept parameter, the collision rate with its 95 % Clopper–Pearson
interval and the distribution of the closest approach to any target, and lists the worst
cells (closest approach first) linked to their recordings (``asvtwin replay FILE``).
"""

from __future__ import annotations

import io
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

from asvtwin.errors import MissingExtraError
from asvtwin.whatif.risk import proportion_ci

__all__ = ["write_parquet", "write_report"]


def write_parquet(rows: list[dict[str, Any]], path: str | Path) -> Path:
    """Write the rows (one per cell) to a Parquet file (pyarrow)."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise MissingExtraError("pyarrow", "sweep") from exc

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    # parameter values of mixed kinds (e.g. 0 and 0.5) become one column type
    norm = []
    for r in rows:
        norm.append({k: (str(v) if k.startswith("param.") else v) for k, v in r.items()})
    pq.write_table(pa.Table.from_pylist(norm), p)
    return p


def _svg(fig: Any) -> str:
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    buf = io.StringIO()
    FigureCanvasSVG(fig).print_svg(buf)
    text = buf.getvalue()
    return text[text.find("<svg"):]


def _figure(name: str, groups: dict[str, list[dict[str, Any]]]) -> str:
    from matplotlib.figure import Figure

    labels = list(groups)
    fig = Figure(figsize=(8.0, 3.2))
    ax1, ax2 = fig.subplots(1, 2)
    rate, err_lo, err_hi = [], [], []
    for k in labels:
        rs = groups[k]
        n, c = len(rs), sum(1 for r in rs if (r["collisions"] or 0) > 0)
        lo, hi = proportion_ci(c, n)
        rate.append(100 * c / n)
        err_lo.append(100 * (c / n - lo))
        err_hi.append(100 * (hi - c / n))
    x = range(len(labels))
    ax1.bar(x, rate, yerr=[err_lo, err_hi], capsize=4, color="#c0392b")
    ax1.set_xticks(list(x), labels)
    ax1.set_xlabel(name)
    ax1.set_ylabel("runs with a collision [%] (95 % CI)")
    data = [[r["min_distance_m"] for r in groups[k] if r["min_distance_m"] is not None]
            for k in labels]
    ax2.boxplot([d if d else [float("nan")] for d in data])
    ax2.set_xticks([i + 1 for i in x], labels)
    ax2.set_xlabel(name)
    ax2.set_ylabel("closest approach to a target [m]")
    fig.tight_layout()
    return _svg(fig)


_TEMPLATE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>asvtwin sweep</title>
<style>body{font-family:sans-serif;max-width:60em;margin:2em auto}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
td.l,th.l{text-align:left}</style></head><body>
<h1>Sweep: {{ n }} runs</h1>
<p>Scenarios: {{ sources|join(', ') }}. Seeds per cell: {{ seeds }}.
Runs with a collision: {{ collided }} of {{ n }} ({{ '%.1f'|format(rate) }} %, 95 % interval
{{ '%.1f'|format(ci[0]) }}–{{ '%.1f'|format(ci[1]) }} %). Runs that met every criterion:
{{ passed }}.</p>
{% for name, svg in figures %}<h2>{{ name }}</h2>{{ svg|safe }}{% endfor %}
<h2>Worst runs (closest approach first)</h2>
<table><tr><th class="l">scenario</th><th class="l">parameters</th><th>seed</th>
<th>closest [m]</th><th>collisions</th><th>groundings</th><th class="l">recording</th></tr>
{% for r in worst %}<tr><td class="l">{{ r.scenario }}</td><td class="l">{{ r.params }}</td>
<td>{{ r.seed }}</td><td>{{ r.min_distance }}</td><td>{{ r.collisions }}</td>
<td>{{ r.groundings }}</td><td class="l"><a href="{{ r.href }}">{{ r.href }}</a></td></tr>
{% endfor %}</table></body></html>
"""


def write_report(rows: list[dict[str, Any]], path: str | Path, *, worst: int = 10) -> Path:
    """Write the HTML report of a sweep's rows to ``path``."""
    try:
        import jinja2
    except ImportError as exc:
        raise MissingExtraError("jinja2", "sweep") from exc

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    pnames = sorted({k for r in rows for k in r if k.startswith("param.")})
    figures = []
    for k in pnames or ["source"]:
        groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
        for r in rows:
            groups[str(r.get(k))].append(r)
        figures.append((k.removeprefix("param."), _figure(k.removeprefix("param."), groups)))
    n = len(rows)
    collided = sum(1 for r in rows if (r["collisions"] or 0) > 0)
    lo, hi = proportion_ci(collided, n) if n else (0.0, 1.0)
    ranked = sorted(rows, key=lambda r: (r["min_distance_m"] is None,
                                         r["min_distance_m"] or 0.0))[:worst]
    bad = [{"scenario": r["scenario"], "seed": r["seed"],
            "params": ", ".join(f"{k.removeprefix('param.')}={r[k]}" for k in pnames),
            "min_distance": "—" if r["min_distance_m"] is None else f"{r['min_distance_m']:.1f}",
            "collisions": r["collisions"], "groundings": r["groundings"],
            "href": Path(os.path.relpath(Path(r["recording"]).resolve(),
                                         p.parent.resolve())).as_posix()}
           for r in ranked]
    html = jinja2.Environment(autoescape=True).from_string(_TEMPLATE).render(
        n=n, sources=sorted({str(r["source"]) for r in rows}),
        seeds=len({r["seed"] for r in rows}), collided=collided,
        rate=100 * collided / max(n, 1), ci=(100 * lo, 100 * hi),
        passed=sum(1 for r in rows if r["passed"]), figures=figures, worst=bad)
    p.write_text(html)
    return p
