"""File formats for measured BRDF data. NumPy only: never imports :mod:`brdffit` or JAX.

Each format lives in its own module and hands its data over as a
:class:`~data_formats.samples.SampleSet` (``to_samples()``), the only thing the fitter reads.
"""

from .merl import (
    MERL_SHAPE,
    N_PD,
    N_TD,
    N_TH,
    SCALE,
    MERLFormatError,
    MERLTable,
    cell_angles,
    cell_directions,
    lookup_linear,
    lookup_nearest,
    merl_index,
    read_merl,
    synthesize,
    write_merl,
)
from .rusinkiewicz import dirs_from_half_diff, half_diff_from_dirs
from .samples import SampleSet

__all__ = [
    "SampleSet",
    "MERLFormatError",
    "MERLTable",
    "read_merl",
    "write_merl",
    "synthesize",
    "merl_index",
    "cell_angles",
    "cell_directions",
    "lookup_nearest",
    "lookup_linear",
    "half_diff_from_dirs",
    "dirs_from_half_diff",
    "N_TH",
    "N_TD",
    "N_PD",
    "MERL_SHAPE",
    "SCALE",
]
from .samplelist import SampleListFormatError, read_samples, write_samples  # noqa: E402

__all__ += ["SampleListFormatError", "read_samples", "write_samples"]
from .tensorfile import TensorFileError, read_tensor_file, write_tensor_file  # noqa: E402

__all__ += ["TensorFileError", "read_tensor_file", "write_tensor_file"]
from .rgl import RGLFormatError, RGLMaterial, read_rgl, synthesize_rgl, write_rgl  # noqa: E402

__all__ += ["RGLFormatError", "RGLMaterial", "read_rgl", "write_rgl", "synthesize_rgl"]
