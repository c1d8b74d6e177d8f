"""``brdffit demo``: synthesize a table from known parameters, fit it, compare, plot."""

from __future__ import annotations


def add_parser(sub, parents) -> None:
    p = sub.add_parser("demo", parents=parents, help="synthesize, fit and plot a known material")
    p.set_defaults(run=run)


def run(args) -> int:
    raise NotImplementedError
