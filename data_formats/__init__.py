"""File formats for measured BRDF data. NumPy only: never imports :mod:`brdffit` or JAX.

Each format lives in its own module and hands its data over as a
:class:`~data_formats.samples.SampleSet` (``to_samples()``), the only thing the fitter reads.
"""

from .samples import SampleSet

__all__ = ["SampleSet"]
from .samplelist import SampleListFormatError, read_samples, write_samples  # noqa: E402
__all__ += ["SampleListFormatError", "read_samples", "write_samples"]
