"""The library's advice in command-line words: ``max_steps`` becomes ``--max-steps``.

Library messages name the Python argument to change (``Increase `max_steps```); the command
line prints them with the flag that sets it instead. :data:`FLAG_FOR` is the one table of which
flag sets which argument (``brdffit fit`` and its ``--mcmc`` group).
"""

from __future__ import annotations

import re

from ..config import OPTIONS

#: Python argument of ``brdffit.fit`` / ``sample_posterior`` → the ``brdffit fit`` flag: the fit
#: options' flags (:data:`brdffit.config.OPTIONS`) and the ``--mcmc`` group's.
FLAG_FOR = {
    **{key: option.flag for key, option in OPTIONS.items() if option.flag},
    "nwalkers": "--walkers", "nsteps": "--steps", "burn": "--burn", "noise": "--noise",
}

_RULES = (
    (re.compile(r"the `(\w+)` loss"), lambda m: f"`--loss {m.group(1)}`"),
    (re.compile(r"pass `noise=<positive number>` to set the noise scale yourself"),
     lambda m: "give the data sigma columns and pass `--noise measured`"),
    (re.compile(r"\bnsteps >= (\d+)"), lambda m: f"--steps {m.group(1)} or more"),
    (re.compile(r"\bnwalkers=(\d+)"), lambda m: f"--walkers {m.group(1)}"),
    (re.compile(r"a larger nsteps"), lambda m: "a larger --steps"),
    (re.compile(r"a smaller subsample"), lambda m: "a smaller --mcmc-subsample"),
    (re.compile(r"\bnwalkers\b"), lambda m: "--walkers"),
    (re.compile(r"\bnsteps\b"), lambda m: "--steps"),
    (re.compile(r"\bburn=(\d+)"), lambda m: f"--burn {m.group(1)}"),
    (re.compile(r"`(\w+)`"), lambda m: f"`{FLAG_FOR.get(m.group(1), m.group(1))}`"),
)


def cli_words(text: str) -> str:
    """``text`` with every suggested Python argument replaced by its ``brdffit fit`` flag."""
    for pattern, repl in _RULES:
        text = pattern.sub(repl, text)
    return text
