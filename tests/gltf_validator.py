"""The Khronos glTF validator (npm ``gltf-validator``), run on a file through Node.

:func:`validate` returns the validator's report (``numErrors``, ``numWarnings``, ``numInfos``,
``messages``) or skips the calling test, saying why, where Node or the package is missing. The
package is looked up as Node does (``NODE_PATH``, ``node_modules`` folders); ``.ci/run``
installs it into its own folder and sets ``NODE_PATH``. To run these tests by hand::

    npm install --prefix ~/.cache/brdffit-node gltf-validator
    NODE_PATH=~/.cache/brdffit-node/node_modules pytest tests/test_hostile_exports.py
"""

from __future__ import annotations

import functools
import json
import shutil
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).parent / "tools" / "validate_gltf.js"


@functools.cache
def _missing() -> str | None:
    node = shutil.which("node")
    if node is None:
        return "Node.js is not installed (the glTF validator runs on it)"
    probe = subprocess.run([node, "-e", "require.resolve('gltf-validator')"],
                           capture_output=True, text=True, timeout=60)
    if probe.returncode != 0:
        return ("the npm package gltf-validator is not found: npm install gltf-validator "
                "and point NODE_PATH at its node_modules folder")
    return None


def validate(path) -> dict:
    """The Khronos validator's report on the glTF (or GLB) file ``path``."""
    reason = _missing()
    if reason is not None:
        pytest.skip(reason)
    run = subprocess.run([shutil.which("node"), str(SCRIPT), str(path)], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, f"the validator made no report on {path}: {run.stderr.strip()}"
    return json.loads(run.stdout)
