"""Audit of the RGL ``.bsdf`` format: hostile files whose fields are consistent with each other
and with the file's size, but whose shapes would make reading the measurement pattern take far
more memory than the file (a few MB asking for GB).

Files are built with :func:`data_formats.write_tensor_file` from the fields Mitsuba's
``measured`` plugin requires, so that every check of the reader passes except the one under
test.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from brdffit.cli import main
from data_formats import RGLFormatError, read_rgl, write_tensor_file
from test_hostile import _one_line_error


def _fields(n_phi=1, n_theta=2, n=2, table=(2, 2)):
    """The fields of a constant (Lambertian-like) RGL material of the given shapes."""
    phi = np.linspace(-np.pi, np.pi, n_phi) if n_phi > 2 else np.zeros(n_phi)
    return {"description": b"hostile", "jacobian": np.array([0], np.uint8),
            "theta_i": np.linspace(0.0, 1.5, n_theta).astype(np.float32),
            "phi_i": phi.astype(np.float32),
            "ndf": np.ones((2, 2), np.float32), "sigma": np.ones((2, 2), np.float32),
            "vndf": np.ones((n_phi, n_theta, *table), np.float32),
            "luminance": np.ones((n_phi, n_theta, n, n), np.float32),
            "rgb": np.full((n_phi, n_theta, 3, n, n), 0.1, np.float32)}


def test_many_incidence_slices_read_in_memory_of_the_file_size(tmp_path):
    """3,000 θi slices of 2 x 2 nodes (a 300 kB file): assigning the Monte Carlo points of the
    weights to their nearest slice compared every point with every slice (65,536 x 3,000
    float64, 1.5 GB, and 6 GB for 12,000 slices). It is a binary search now."""
    path = tmp_path / "slices.bsdf"
    write_tensor_file(path, _fields(n_theta=3000))
    material = read_rgl(path)
    tracemalloc.start()
    try:
        samples = material.to_samples(count=1 << 17)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(samples) == 3000 * 4
    assert peak < 64 << 20, f"peaked at {peak / 2**20:.0f} MiB for a {path.stat().st_size:,}-byte file"


def test_a_pattern_beyond_the_limit_is_one_error(tmp_path, monkeypatch, capsys):
    """A file whose pattern has more pairs than the reader's limit is refused when read (the
    pattern and its weights take about 20 times the file), in one line, exit 2 (here the limit
    is lowered so that the file stays small)."""
    import data_formats.rgl._io as rgl_io

    path = tmp_path / "wide.bsdf"
    write_tensor_file(path, _fields(n_theta=4, n=64))
    assert len(read_rgl(path).to_samples(weights=False)) == 4 * 64 * 64
    monkeypatch.setattr(rgl_io, "MAX_PATTERN_PAIRS", 4 * 64 * 64 - 1)
    with pytest.raises(RGLFormatError, match="16,384 direction pairs"):
        read_rgl(path)
    for command in (["info"], ["fit", "-m", "ggx"]):
        assert main([command[0], str(path), *command[1:]]) == 2
        _one_line_error(capsys.readouterr().err, str(path), "limit")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wide.bsdf"]

