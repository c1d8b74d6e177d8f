"""Spectra to linear sRGB, as a spectral render under a white (CIE D65) light reads them.

RGL materials are measured spectrally (``spectra``, 360-1000 nm). Mitsuba 3's RGB variants refuse
spectral files (``measured.cpp``: "Measurements in spectral format require the use of a spectral
variant"); a spectral variant renders the spectrum, and an sRGB film integrates it against the
CIE 1931 2° colour matching functions. The reflectance a renderer shows under a white light is
therefore

.. math::

    \\mathrm{RGB} = M_{XYZ \\to sRGB} \\frac{\\int S(\\lambda) E(\\lambda)
    \\bar{\\mathbf{x}}(\\lambda) \\, d\\lambda}{\\int E(\\lambda) \\bar y(\\lambda) \\, d\\lambda}

with ``E`` the CIE D65 illuminant (the white of sRGB, so a perfect white reflector gives
``(1, 1, 1)``), the integral over Mitsuba's CIE range 360-830 nm, ``S`` interpolated linearly
between the file's wavelengths and held constant beyond its ends (Mitsuba's ``Warp2D3``
interpolation in the wavelength parameter, weights clamped), and ``M`` the sRGB matrix (IEC
61966-2-1, Mitsuba's ``xyz_to_srgb``). This is Mitsuba's ``spectrum_list_to_srgb(..., d65=True,
bounded=False)`` up to its quadrature and without its clamp of negative (out-of-gamut) values
(and it counts a spectrum as 0 outside its wavelengths, where the BSDF holds the end values).
The reduction is linear, so :class:`~data_formats.rgl.RGLMaterial` applies it to the tables once
(interpolation commutes with it).

Tables: CIE 1931 2° colour matching functions and CIE D65 (relative, 100 at 560 nm) at 5 nm from
360 to 830 nm, as Mitsuba 3 tabulates and linearly interpolates them (``cie1931_xyz``,
``cie_d65``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["spectra_to_rgb_matrix", "spectra_to_rgb", "CIE_WAVELENGTHS", "CIE_XYZ", "CIE_D65",
           "XYZ_TO_SRGB"]

#: Wavelengths of the tables, nm.
CIE_WAVELENGTHS = np.arange(360.0, 831.0, 5.0)
#: CIE 1931 2° colour matching functions x̄, ȳ, z̄ at :data:`CIE_WAVELENGTHS` ``(3, 95)``.
CIE_XYZ = np.array([
    [
    0.0001299, 0.000232100007, 0.000414899987, 0.000741600001, 0.00136800006, 0.00223600003,
    0.00424299994, 0.00765000004, 0.0143100005, 0.0231899992, 0.0435100012, 0.0776299983,
    0.134379998, 0.214770004, 0.283899993, 0.328500003, 0.348280013, 0.348060012, 0.336199999,
    0.318699986, 0.290800005, 0.251100004, 0.195360005, 0.142100006, 0.0956400037,
    0.0579500087, 0.0320100002, 0.0147000002, 0.00490000006, 0.00240000011, 0.00930000003,
    0.0291000009, 0.0632700026, 0.1096, 0.1655, 0.225749895, 0.290399998, 0.359699994,
    0.433449894, 0.512050092, 0.594500005, 0.67839998, 0.762099981, 0.842499971, 0.916299999,
    0.978600025, 1.02629995, 1.05669999, 1.06219995, 1.04560006, 1.00259995, 0.938399971,
    0.854449928, 0.751399994, 0.642400026, 0.541899979, 0.447899997, 0.360799998, 0.283499986,
    0.218700007, 0.164900005, 0.121200003, 0.0873999968, 0.0636000037, 0.046769999,
    0.0329000019, 0.0227000006, 0.0158399995, 0.0113591598, 0.00811091624, 0.00579034584,
    0.00410945714, 0.00289932708, 0.00204918999, 0.00143997103, 0.00099994929, 0.000690078596,
    0.000476021291, 0.000332301104, 0.000234826104, 0.000166150494, 0.000117413001,
    8.30752688e-05, 5.87065188e-05, 4.15099385e-05, 2.93532594e-05, 2.06738296e-05,
    1.45597696e-05, 1.02539798e-05, 7.22145614e-06, 5.085868e-06, 3.58165198e-06,
    2.52252494e-06, 1.77650895e-06, 1.25114104e-06
    ],
    [
    3.91699996e-06, 6.96500001e-06, 1.23899999e-05, 2.202e-05, 3.89999987e-05, 6.39999998e-05,
    0.000119999997, 0.000216999993, 0.000395999989, 0.000639999984, 0.00121000002,
    0.00218000007, 0.00400000019, 0.00730000017, 0.0115999999, 0.0168399997, 0.023,
    0.0297999997, 0.0379999988, 0.0480000004, 0.0599999987, 0.0738999993, 0.0909800008,
    0.112599999, 0.139019996, 0.169300005, 0.208020002, 0.258599997, 0.323000014, 0.407299995,
    0.503000021, 0.608200014, 0.709999979, 0.793200016, 0.861999989, 0.914850116, 0.953999996,
    0.980300009, 0.994950116, 1, 0.995000005, 0.978600025, 0.952000022, 0.915400028,
    0.870000005, 0.816299975, 0.757000029, 0.694899976, 0.630999982, 0.566799998, 0.503000021,
    0.441199988, 0.381000012, 0.32100001, 0.264999986, 0.216999993, 0.174999997, 0.1382,
    0.107000001, 0.0816000029, 0.0610000007, 0.0445800014, 0.0320000015, 0.0231999997,
    0.0170000009, 0.0119200004, 0.00820999965, 0.00572300004, 0.00410200004, 0.00292899995,
    0.00209100009, 0.00148400001, 0.00104700006, 0.000739999989, 0.000520000001,
    0.000361100014, 0.000249200006, 0.000171899999, 0.000119999997, 8.47999981e-05,
    5.99999985e-05, 4.23999991e-05, 2.99999992e-05, 2.11999995e-05, 1.49899997e-05,
    1.05999998e-05, 7.46570004e-06, 5.25779978e-06, 3.7028999e-06, 2.60780007e-06,
    1.83659995e-06, 1.29340003e-06, 9.10929998e-07, 6.41529994e-07, 4.51809996e-07
    ],
    [
    0.000606100017, 0.001086, 0.00194600003, 0.003486, 0.00645000115, 0.0105499905,
    0.0200500097, 0.0362100005, 0.0678500086, 0.110200003, 0.207399994, 0.371300012,
    0.645600021, 1.0390501, 1.38559997, 1.62295997, 1.74705994, 1.78260005, 1.77210999,
    1.74409997, 1.66919994, 1.52810001, 1.28763998, 1.04190004, 0.812950075, 0.61619997,
    0.46518001, 0.353300005, 0.272000015, 0.212300003, 0.158199996, 0.111699998, 0.0782499909,
    0.0572500117, 0.0421600007, 0.02984, 0.0203000009, 0.0133999996, 0.00874999911,
    0.00574999908, 0.00389999989, 0.00274999905, 0.00209999993, 0.00179999997, 0.00165000104,
    0.00139999995, 0.00109999999, 0.00100000005, 0.00079999998, 0.000600000028,
    0.000339999999, 0.000239999994, 0.000190000006, 9.99999975e-05, 4.99999915e-05,
    2.99999992e-05, 1.99999995e-05, 9.99999975e-06, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
    ],
])
#: CIE standard illuminant D65 (relative spectral power) at :data:`CIE_WAVELENGTHS`.
CIE_D65 = np.array([
    46.6383032, 49.3637006, 52.0891009, 51.0323022, 49.9754976, 52.3117995, 54.6482017,
    68.7014999, 82.7548984, 87.1204, 91.4860018, 92.4588984, 93.4318009, 90.0569984,
    86.6822962, 95.7735964, 104.864997, 110.935997, 117.008001, 117.410004, 117.811995,
    116.336005, 114.861005, 115.391998, 115.923002, 112.367001, 108.811, 109.082007,
    109.353994, 108.578004, 107.802002, 106.296001, 104.789999, 106.239, 107.689004,
    106.047003, 104.405001, 104.224994, 104.046002, 102.023004, 99.9999947, 98.1670997,
    96.3341988, 96.0610964, 95.788, 92.2368017, 88.6856035, 89.3459043, 90.0062051,
    89.8025953, 89.5990977, 88.6489011, 87.6986986, 85.4935989, 83.2885996, 83.4938969,
    83.6992061, 81.8630008, 80.0268015, 80.1206994, 80.2145973, 81.2462, 82.2778027,
    80.280998, 78.284205, 74.0027, 69.7213012, 70.6652017, 71.6091022, 72.9789983, 74.3490006,
    67.9765038, 61.604001, 65.7447978, 69.8856005, 72.4862953, 75.086996, 69.339797,
    63.5927041, 55.0054009, 46.418201, 56.6118032, 66.8053966, 65.0941033, 63.3828042,
    63.8434015, 64.3039988, 61.8779, 59.4519015, 55.7054017, 51.9590022, 54.6997975,
    57.4406046, 58.8765, 60.3125017
])
#: XYZ -> linear sRGB (IEC 61966-2-1).
XYZ_TO_SRGB = np.array([[3.240479, -1.537150, -0.498535],
                        [-0.969256, 1.875991, 0.041556],
                        [0.055648, -0.204043, 1.057311]])
_STEP = 0.5  # nm, the quadrature step


def spectra_to_rgb_matrix(wavelengths) -> np.ndarray:
    """``(3, n_λ)``: linear sRGB of a spectrum sampled at ``wavelengths`` (nm, increasing) is
    this matrix times the samples (module docstring)."""
    wl = np.asarray(wavelengths, dtype=np.float64)
    if wl.ndim != 1 or len(wl) < 1 or np.any(np.diff(wl) <= 0) or not np.all(np.isfinite(wl)):
        raise ValueError(f"spectra_to_rgb_matrix: wavelengths must be finite and increasing, "
                         f"got {wl[:8]}")
    lam = np.arange(CIE_WAVELENGTHS[0], CIE_WAVELENGTHS[-1] + _STEP / 2, _STEP)
    cmf = np.stack([np.interp(lam, CIE_WAVELENGTHS, c) for c in CIE_XYZ])
    light = np.interp(lam, CIE_WAVELENGTHS, CIE_D65)
    # Hat functions of the file's linear interpolation, constant beyond its ends.
    eye = np.eye(len(wl))
    hats = np.stack([np.interp(lam, wl, eye[k]) for k in range(len(wl))]) if len(wl) > 1 \
        else np.ones((1, len(lam)))
    weight = np.full(len(lam), _STEP)
    weight[[0, -1]] *= 0.5  # trapezoid
    xyz = (cmf * light * weight) @ hats.T
    xyz /= np.sum(cmf[1] * light * weight)
    return XYZ_TO_SRGB @ xyz


def spectra_to_rgb(wavelengths, values) -> np.ndarray:
    """Linear sRGB ``(..., 3)`` of spectra ``(..., n_λ)`` sampled at ``wavelengths``."""
    return np.einsum("cl,...l->...c", spectra_to_rgb_matrix(wavelengths),
                     np.asarray(values, dtype=np.float64))
