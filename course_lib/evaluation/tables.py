"""Results tables that set our numbers beside a paper's, as Markdown, HTML or a dict.

    t = table({"VAE-LSTM": {70: 0.011, 90: 0.015}},
              paper={"VAE-LSTM": {70: 1.45, 90: 1.75}},
              columns=[70, 90], units="m^2 (paper: its own units)",
              title="Prediction error at frame")
    print(t.markdown())   # in a notebook the object renders itself as HTML

Each model gets one row "(ours)" and, when the paper reports it, one row
"(paper)"; missing numbers print as an em dash.  No pandas needed.

Used by every notebook's "the paper's table re-done on our data" section.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence

__all__ = ["ResultsTable", "mean_sd", "over_seeds", "table"]

_MISSING = "\u2014"


def _fmt(value, digits: int) -> str:
    """A number with ``digits`` significant digits ('g' format); None/NaN -> an em dash; strings as given."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return _MISSING
    if isinstance(value, str):
        return value
    return f"{float(value):.{digits}g}"


def mean_sd(mean: float, sd: float, digits: int = 3) -> str:
    """'mean +- sd' for a table cell, both with ``digits`` significant digits of the mean's size:
    mean_sd(2512.3, 140.7) -> '2512 ± 141', mean_sd(0.6543, 0.0121) -> '0.654 ± 0.012'."""
    if not (math.isfinite(mean) and math.isfinite(sd)):
        return f"{mean} ± {sd}"
    decimals = max(0, digits - 1 - int(math.floor(math.log10(abs(mean)))) if mean else digits - 1)
    return f"{mean:.{decimals}f} ± {sd:.{decimals}f}"



def over_seeds(per_seed: list):
    """Nested dicts of numbers, one per (generation) seed -> (mean, sd) of the same shape: the sd with ddof 1,
    0 for a single seed; bools and ints are averaged too.
    over_seeds([{"a": 1}, {"a": 3}]) -> ({"a": 2.0}, {"a": 1.414...})."""
    first = per_seed[0]
    if isinstance(first, Mapping):
        pairs = {k: over_seeds([r[k] for r in per_seed]) for k in first}
        return {k: m for k, (m, _) in pairs.items()}, {k: sd for k, (_, sd) in pairs.items()}
    values = [float(v) for v in per_seed]
    mean = math.fsum(values) / len(values)
    if len(values) < 2:
        return mean, 0.0
    return mean, math.sqrt(math.fsum((v - mean) ** 2 for v in values) / (len(values) - 1))

class ResultsTable:
    """Rows of (model, source, {column: value}); render with .markdown(), .html(), .to_dict()."""

    def __init__(self, rows: list[tuple[str, str, dict]], columns: list, units: str = "",
                 title: str = "", digits: int = 4):
        self.rows, self.columns, self.units, self.title, self.digits = rows, columns, units, title, digits

    def _header(self) -> list[str]:
        return ["model", "source"] + [str(c) for c in self.columns]

    def _cells(self) -> list[list[str]]:
        return [[model, source] + [_fmt(values.get(c), self.digits) for c in self.columns]
                for model, source, values in self.rows]

    def _caption(self) -> str:
        parts = [p for p in (self.title, f"units: {self.units}" if self.units else "") if p]
        return "; ".join(parts)

    def markdown(self) -> str:
        """A GitHub-flavoured Markdown table with the title and units as a caption line."""
        head = self._header()
        lines = [f"**{self._caption()}**", ""] if self._caption() else []
        lines += ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * 2 + ["---:"] * (len(head) - 2)) + "|"]
        lines += ["| " + " | ".join(row) + " |" for row in self._cells()]
        return "\n".join(lines)

    def html(self) -> str:
        """An HTML <table> with a <caption>; values right-aligned."""
        esc = html.escape
        cap = f"<caption>{esc(self._caption())}</caption>" if self._caption() else ""
        head = "".join(f"<th>{esc(h)}</th>" for h in self._header())
        body = "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" if i < 2 else f'<td style="text-align:right">{esc(c)}</td>'
                                        for i, c in enumerate(row)) + "</tr>" for row in self._cells())
        return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"

    def _repr_html_(self) -> str:
        return self.html()

    def __str__(self) -> str:
        return self.markdown()

    __repr__ = __str__

    def to_dict(self) -> dict:
        """{"columns", "units", "title", "rows": [{"model", "source", "values": {column: value}}]}."""
        return {"columns": list(self.columns), "units": self.units, "title": self.title,
                "rows": [{"model": m, "source": s, "values": {c: v.get(c) for c in self.columns}}
                         for m, s, v in self.rows]}


def _check_rows(rows, name: str) -> dict:
    if not isinstance(rows, Mapping):
        raise TypeError(f"table: {name} must be a dict {{model: {{column: value}}}}, got {type(rows).__name__}")
    for model, values in rows.items():
        if not isinstance(values, Mapping):
            raise TypeError(f"table: {name}[{model!r}] must be a dict {{column: value}}, got {type(values).__name__}")
    return dict(rows)


def table(rows: Mapping[str, Mapping], paper: Mapping[str, Mapping] | None = None,
          columns: Sequence | None = None, units: str = "", title: str = "", digits: int = 4) -> ResultsTable:
    """Our results beside the paper's: rows {model: {column: value}}, paper alike -> ResultsTable.

    columns: the columns to show, in order (default: every key seen, ours first).  A model
    found only in ``paper`` still gets its paper row; ours come first, in the given order.
    """
    ours, theirs = _check_rows(rows, "rows"), _check_rows(paper or {}, "paper")
    if columns is None:
        columns = list(dict.fromkeys(k for d in (*ours.values(), *theirs.values()) for k in d))
    models = list(dict.fromkeys([*ours, *theirs]))
    out = []
    for model in models:
        if model in ours:
            out.append((model, "ours", dict(ours[model])))
        if model in theirs:
            out.append((model, "paper", dict(theirs[model])))
    return ResultsTable(out, list(columns), units, title, digits)
