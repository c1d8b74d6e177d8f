"""Text tables whose columns are sized to their content: the one layout of every printed table.

:func:`columns` lays out rows of cells (strings) so that each column is as wide as its widest
cell (header included), so a long model or parameter name widens its column instead of
shifting the cells after it. Widths count characters (``len``); every name and number printed
by brdffit is one character per cell of a terminal.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["columns"]


def columns(rows: Sequence[Sequence[str]], align: str, *, indent: str = "", gap: str = "  ",
            rule: bool = False, minimum: Sequence[int] = ()) -> list[str]:
    """The lines of ``rows`` laid out in columns.

    Args:
        rows: the cells, row by row, the header (if any) first; every row has one cell per
            character of ``align``.
        align: one character per column: ``<`` left-aligned, ``>`` right-aligned.
        indent: put before every line.
        gap: between two columns.
        rule: a line of dashes, as wide as the table, under the first row (the header).
        minimum: the least width of each column, in order (columns beyond it: none); for a
            table whose first column lines up with other text.

    Trailing blanks are stripped from every line (a left-aligned last column adds none).
    """
    cells = [[str(c) for c in row] for row in rows]
    for row in cells:
        if len(row) != len(align):
            raise ValueError(f"a row of {len(row)} cells for {len(align)} columns: {row!r}")
    widths = [max([len(row[i]) for row in cells] + [minimum[i] if i < len(minimum) else 0])
              for i in range(len(align))]
    lines = [(indent + gap.join(c.rjust(w) if a == ">" else c.ljust(w)
                                for c, w, a in zip(row, widths, align))).rstrip()
             for row in cells]
    if rule and lines:
        lines.insert(1, indent + "-" * (sum(widths) + len(gap) * (len(widths) - 1)))
    return lines
