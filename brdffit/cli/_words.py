"""The library's advice in command-line words: ``max_steps`` becomes ``--max-steps``.

Library messages name the Python argument to change (``Increase `max_steps```); the command
line prints them with the flag that sets it instead. :data:`FLAG_FOR` is the one table of which
flag sets which argument (``brdffit fit`` and its ``--mcmc`` group).
"""

from __future__ import annotations

import re

from ..config import OPTIONS
from ..posterior.options import MCMC_OPTIONS

#: Python argument of ``brdffit.fit`` / ``sample_posterior`` → the ``brdffit fit`` flag: the fit
#: options' flags (:data:`brdffit.config.OPTIONS`), then the ``--mcmc`` group's
#: (:data:`brdffit.posterior.options.MCMC_OPTIONS`) where the name is not a fit option's
#: (``subsample`` is the fit's ``--subsample``).
FLAG_FOR = {
    **{key: option.flag for key, option in MCMC_OPTIONS.items() if option.flag},
    **{key: option.flag for key, option in OPTIONS.items() if option.flag},
}

#: The ``--mcmc`` group's flag of each sampler option (``subsample``: ``--mcmc-subsample``).
_MCMC = {key: option.flag for key, option in MCMC_OPTIONS.items()}

_RULES = (
    (re.compile(r"the `(\w+)` loss"), lambda m: f"`--loss {m.group(1)}`"),
    (re.compile(r"pass `noise=<positive number>` to set the noise scale yourself"),
     lambda m: f"give the data sigma columns and pass `{_MCMC['noise']} measured`"),
    (re.compile(r"\bnsteps >= (\d+)"), lambda m: f"{_MCMC['nsteps']} {m.group(1)} or more"),
    (re.compile(r"\bnwalkers=(\d+)"), lambda m: f"{_MCMC['nwalkers']} {m.group(1)}"),
    (re.compile(r"a larger nsteps"), lambda m: f"a larger {_MCMC['nsteps']}"),
    (re.compile(r"a smaller subsample"), lambda m: f"a smaller {_MCMC['subsample']}"),
    (re.compile(r"\bnwalkers\b"), lambda m: _MCMC["nwalkers"]),
    (re.compile(r"\bnsteps\b"), lambda m: _MCMC["nsteps"]),
    (re.compile(r"\bburn=(\d+)"), lambda m: f"{_MCMC['burn']} {m.group(1)}"),
    (re.compile(r"`(\w+)`"), lambda m: f"`{FLAG_FOR.get(m.group(1), m.group(1))}`"),
)


def cli_words(text: str) -> str:
    """``text`` with every suggested Python argument replaced by its ``brdffit fit`` flag."""
    for pattern, repl in _RULES:
        text = pattern.sub(repl, text)
    return text
