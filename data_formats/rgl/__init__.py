"""The RGL material format (Dupuy & Jakob 2018): ``.bsdf`` tensor files as Mitsuba 3 renders them.

NumPy only. One module per idea, every public name re-exported here: ``_marginal`` (a port of
Mitsuba's ``Marginal2D`` warp), ``_material`` (:class:`RGLMaterial`: the fields, evaluation as
Mitsuba's ``measured`` plugin does it, the measurement pattern as a ``SampleSet``), ``_io``
(:func:`read_rgl`, :func:`write_rgl`, :class:`RGLFormatError`), ``_synthesize``
(:func:`synthesize_rgl`, a virtual measurement of any NumPy BRDF), ``_spectral`` (spectra to RGB).
"""

from ._io import RGLFormatError, read_rgl, write_rgl
from ._marginal import Marginal2D
from ._material import RGLMaterial
from ._spectral import spectra_to_rgb, spectra_to_rgb_matrix
from ._synthesize import synthesize_rgl

__all__ = ["RGLFormatError", "RGLMaterial", "read_rgl", "write_rgl", "synthesize_rgl",
           "Marginal2D", "spectra_to_rgb", "spectra_to_rgb_matrix"]
