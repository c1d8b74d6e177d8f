"""Spectra to linear sRGB (placeholder until the CIE tables are in)."""

import numpy as np

__all__ = ["spectra_to_rgb_matrix", "spectra_to_rgb"]


def spectra_to_rgb_matrix(wavelengths):
    raise NotImplementedError("spectral RGL files are not supported yet")


def spectra_to_rgb(wavelengths, values):
    return np.einsum("cl,...l->...c", spectra_to_rgb_matrix(wavelengths), values)
