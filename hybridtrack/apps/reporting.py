"""Reproduction reports: ``{"rows": [...], "protocol": {...}}`` JSON and the matching markdown table.

Every script in ``experiments/`` ends with :func:`write_report`: the rows are
the reproduced table (one dict per table row), the protocol says how they were
made (parameters, seeds, number of runs, choices the seed leaves open, the
command).  The markdown file holds the same rows as a table, ready to paste
into ``docs/results.md``.  Both files are written atomically.

A :class:`Column` picks ``row[key]`` (or ``row[key][index]`` for a list) and
formats it; ``None`` and NaN print as ``–``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np


@attrs.frozen
class Column:
    """One markdown column: ``header``, the row ``key`` (element ``index`` of a list value), a format spec."""

    key: str
    header: str
    format: str = ".4g"
    index: int | None = None

    def cell(self, row: Mapping[str, Any]) -> str:
        if self.key not in row:
            raise KeyError(f"column {self.header!r}: row has no {self.key!r} (keys: {sorted(row)})")
        value = row[self.key]
        if self.index is not None and value is not None:
            value = value[self.index]
        if value is None or (isinstance(value, float) and math.isnan(value)):
            return "–"
        if isinstance(value, (list, tuple)):
            return ", ".join(format(v, self.format) for v in value)
        if isinstance(value, str):
            return value
        return format(value, self.format)


def plain(value: Any) -> Any:
    """``value`` with numpy scalars/arrays turned into Python numbers/lists and NaN into ``None`` (strict JSON)."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, (np.ndarray, np.generic)):  # a numpy scalar's tolist() is its item()
        return plain(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def markdown_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[Column]) -> str:
    """A GitHub-flavoured markdown table of ``rows``."""
    if not columns:
        raise ValueError("markdown_table: no columns")
    lines = ["| " + " | ".join(c.header for c in columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(c.cell(row) for c in columns) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_report(
    json_path: str | os.PathLike,
    rows: Iterable[Mapping[str, Any]],
    protocol: Mapping[str, Any],
    *,
    columns: Sequence[Column],
    title: str,
    markdown_path: str | os.PathLike | None = None,
    notes: str = "",
) -> tuple[Path, Path]:
    """Write the JSON report and its markdown table (default: the JSON path with ``.md``); return both paths.

    ``notes`` (markdown) follows the table, e.g. the seed's figures or what is pending.
    """
    rows = [plain(dict(row)) for row in rows]
    json_path = Path(json_path)
    markdown_path = Path(markdown_path) if markdown_path is not None else json_path.with_suffix(".md")
    text = json.dumps({"rows": rows, "protocol": plain(dict(protocol))}, indent=2, allow_nan=False) + "\n"
    table = f"### {title}\n\n" + markdown_table(rows, columns) + (f"\n{notes.strip()}\n" if notes.strip() else "")
    for path, content in ((json_path, text), (markdown_path, table)):  # each written atomically
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f".{path.name}.tmp-{os.getpid()}")
        temporary.write_text(content, encoding="utf-8")
        os.replace(temporary, path)
    return json_path, markdown_path


def save_figure(figure, path: str | os.PathLike, dpi: int = 100) -> Path:
    """Write a matplotlib ``figure`` to ``path`` (PNG; parent folders created) at ``dpi``, close it, return the path."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    return path
