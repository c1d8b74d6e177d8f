r"""The classic models of the MERL-fitting studies, as the published fits define them.

Ngan, Durand & Matusik 2005 ("Experimental Analysis of BRDF Models", EGSR) and Löw, Kronander,
Ynnerman & Unger 2012 ("BRDF Models for Accurate and Efficient Rendering of Glossy Surfaces",
ACM TOG 31(1)) fitted every MERL material with a Lambertian plus one specular model and
published the parameters. The BSDF benchmark project (bbm, ``include/bsdfmodel/ngan.h``,
``low.h`` and the headers they include) implements each model exactly as those parameters mean
it; the models here are transcriptions of bbm's, so that a published line, converted by its
:class:`~brdffit.models.published.PublishedForm`, reproduces bbm's own values
(``tests/test_published_models.py``). Every model is ``f = ρ_d/π + f_s`` (bbm's
``Aggregate(Lambertian(albedo), …)``) with ``diffuse = ρ_d``, and ``specular`` (RGB) is bbm's
``albedo`` of the specular model, a free scale ``k_s``. Directions as everywhere
(:mod:`brdffit.terms._math`); ``h`` the half vector, ``c_i = n·ω_i``, ``c_o = n·ω_o``.

* ``ngan-cooktorrance``, ``low-cooktorrance``: Cook & Torrance 1982 with Beckmann's ``D``
  (:class:`~brdffit.terms.ndf.Beckmann`) and the V-groove ``G``
  (:func:`~brdffit.terms.masking.G2_vgroove`), ``f_s = k_s D G F / (π c_i c_o)``; Ngan's ``F``
  is Schlick's with ``F0`` (bbm's ``eta`` *is* ``F0``), Löw's the exact dielectric Fresnel of
  an index ``η`` (Cook & Torrance's form), and Löw's ``D`` lacks Beckmann's ``1/π`` (bbm's
  ``beckmann<…, Normalize=false>``).
* ``ngan-ashikhmin-shirley``, ``low-ashikhmin-shirley``: the isotropic specular lobe of
  Ashikhmin & Shirley 2000, ``f_s = k_s (n+1)/(8π) (n·h)ⁿ F(h·ω_i) / ((h·ω_i) max(c_i, c_o))``,
  with Schlick's ``F0`` (Ngan) or the dielectric ``η`` (Löw).
* ``ward``, ``ward-duer``: Ward 1992 and Dür 2006,
  ``f_s = k_s exp(−tan²θ_h/α²) / (4π α² √(c_i c_o))`` and ``… / (4π α² c_i c_o)``.
* ``ngan-blinn-phong``: bbm's ``phong`` (the modified Phong of Lafortune & Willems 1994):
  ``f_s = k_s (n+2)/(2π) max(0, R(ω_i)·ω_o)ⁿ`` with ``R`` the mirror about the normal.
* ``lafortune``, ``lafortune-2``, ``lafortune-3``: Lafortune et al. 1997 with Ngan's
  normalisation, one to three lobes; see :func:`lafortune_lobe`.

The conventions bbm picks (which parameter is an index and which a reflectance, where ``π``
goes) are in each lobe's docstring and in ``docs/literature-models-classic.md``.
"""

from __future__ import annotations

from functools import partial

import jax.numpy as jnp
import numpy as np

from ..terms._math import dot, half_vector
from ..terms.diffuse import lambert
from ..terms.fresnel import dielectric, ior_from_f0, schlick
from ..terms.masking import G2_vgroove
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import Beckmann, BlinnPhong
from .published import PublishedForm, register_published
from .registry import Model, Param, register
from .standard import DIFFUSE

#: Beckmann's half width over GGX's (``tan²θ½ = α_b² ln 2`` against ``α²(√2 − 1)``): a start
#: hook's Beckmann roughness from the features' GGX ``α``.
BECKMANN_PER_GGX = float(np.sqrt((np.sqrt(2.0) - 1.0) / np.log(2.0)))

SPECULAR = Param("specular", (3,), 0.0, 4.0, 0.1, "specular scale k_s (RGB), bbm's albedo of the "
                 "specular model", per_channel=True)
#: Beckmann roughness: Ngan's fits span 0.005–0.94, Löw's 0.0018–2.1.
ALPHA = Param("alpha", (), 1e-3, 2.5, 0.1, "Beckmann roughness α (bbm's roughness)", log=True)
F0 = Param("f0", (), 0.0, 1.0, 0.5, "Schlick's F0, scalar (bbm's eta of Ngan's Cook–Torrance, "
           "fresnelReflectance of Ngan's Ashikhmin–Shirley)")
ETA = Param("eta", (), 1.0, 100.0, 1.5, "index of refraction η of the dielectric Fresnel, scalar")
#: Phong-like exponents: Ngan's Blinn–Phong fits span 1.45–1.2e5, Löw's Ashikhmin–Shirley
#: 0.038–6.2e5.
EXPONENT = Param("exponent", (), 0.01, 1e6, 100.0, "lobe exponent n (bbm's sharpness)", log=True)


# -- the specular lobes -------------------------------------------------------------------------
def _vis(wi, wo):
    return (wi[..., 2] > 0) & (wo[..., 2] > 0)


def cook_torrance(ndf, fresnel, wi, wo):
    r"""``D G F / (π c_i c_o)`` with the V-groove ``G``: Cook & Torrance 1982's specular term
    ``R_s = F D G / (π (n·l)(n·v))``, bbm's ``microfacet<…, microfacet_n::Cook>``; that is
    ``4/π`` times :func:`~brdffit.terms.microfacet.microfacet_specular`'s
    ``D G F / (4 c_i c_o)`` (Walter et al. 2007's normalisation)."""
    return (4.0 / jnp.pi) * microfacet_specular(ndf, fresnel, wi, wo, g2=G2_vgroove)


def ashikhmin_shirley(exponent, fresnel, wi, wo):
    r"""The isotropic specular lobe of Ashikhmin & Shirley 2000 (eq. 4), bbm's ``ashikhminshirley``:

    .. math::  f_s = \frac{n + 1}{8\pi}\,\frac{(\mathbf n\cdot\mathbf h)^n\,F(\mathbf h\cdot\omega_i)}
        {(\mathbf h\cdot\omega_i)\max(c_i, c_o)}

    ``(n·h)ⁿ`` is Blinn–Phong's ``D`` times ``2π/(n+2)`` (:class:`~brdffit.terms.ndf.BlinnPhong`,
    accurate for the exponents of 10⁵ that polished materials fit). ``(…, 1)`` for a scalar
    Fresnel parameter."""
    h = half_vector(wi, wo)
    hi = dot(h, wi)
    den = hi * jnp.maximum(wi[..., 2], wo[..., 2])
    ok = _vis(wi, wo) & (den > 0)
    lobe = BlinnPhong(exponent).D(h) * (exponent + 1.0) / (4.0 * (exponent + 2.0))
    lobe = jnp.where(ok, lobe / jnp.where(ok, den, 1.0), 0.0)
    return fresnel(hi) * lobe[..., None]


def ward(alpha, wi, wo, duer=False):
    r"""Ward's isotropic Gaussian lobe, bbm's ``ward`` (Walter's notes on Ward 1992) and, with
    ``duer``, ``wardduer`` (Dür 2006):

    .. math::  f_s = \frac{e^{-\tan^2\theta_h/\alpha^2}}{4\pi\alpha^2\sqrt{c_i c_o}}, \qquad
        f_s^\text{Dür} = \frac{e^{-\tan^2\theta_h/\alpha^2}}{4\pi\alpha^2 c_i c_o}

    ``e^{−tan²θ_h/α²}/(πα²)`` is Beckmann's ``D(h)`` times ``(n·h)⁴``
    (:class:`~brdffit.terms.ndf.Beckmann`, RTR eq. 9.35). Returns ``(...)``."""
    h = half_vector(wi, wo)
    ci, co = wi[..., 2], wo[..., 2]
    ok = _vis(wi, wo)
    norm = ci * co if duer else jnp.sqrt(jnp.where(ok, ci * co, 1.0))
    lobe = Beckmann(alpha).D(h) * h[..., 2] ** 4 / 4.0
    return jnp.where(ok, lobe / jnp.where(ok, norm, 1.0), 0.0)


def cosine_lobe(cos, exponent):
    r"""``(n + 2)/(2π) max(0, cos)ⁿ``, the normalised cosine power of the modified Phong lobe
    (Lafortune & Willems 1994), computed as ``exp(n log cos)``. Returns ``cos``'s shape."""
    pos = cos > 0
    power = jnp.exp(exponent * jnp.log(jnp.where(pos, cos, 1.0)))
    return jnp.where(pos, (exponent + 2.0) / (2.0 * jnp.pi) * power, 0.0)


def phong(exponent, wi, wo):
    r"""bbm's ``phong`` lobe (the alias of Ngan's Blinn–Phong): ``(n+2)/(2π) max(0, R(ω_i)·ω_o)ⁿ``,
    ``R(ω) = (−ω_x, −ω_y, ω_z)``. Returns ``(...)``."""
    cos = -wi[..., 0] * wo[..., 0] - wi[..., 1] * wo[..., 1] + wi[..., 2] * wo[..., 2]
    return jnp.where(_vis(wi, wo), cosine_lobe(cos, exponent), 0.0)


def lafortune_lobe(psi, exponent, wi, wo):
    r"""One Lafortune lobe with Ngan's normalisation (bbm's ``nganlafortune``):

    .. math::  f_s = \frac{n + 2}{2\pi}\,
        \frac{\max(0,\ C_{xy}(\omega_{i,x}\omega_{o,x} + \omega_{i,y}\omega_{o,y}) + C_z\,\omega_{i,z}\omega_{o,z})^n}
             {\max(C_z^2, C_{xy}^2)^{n/2}}

    (Lafortune et al. 1997 eq. 4, times Ngan's factor). The value depends on ``(C_xy, C_z)``
    only through its direction, so the lobe takes ``(C_xy, C_z) = (cos ψ, sin ψ)``:
    ``ψ = 3π/4`` is the modified Phong lobe about the mirror direction (:func:`phong`), larger
    ``ψ`` tilts it towards grazing (``ψ = π``: ``C_z = 0``), ``ψ < π/2`` makes it
    retro-reflective. The base ``d/max(|C_xy|, |C_z|) ≤ 1`` is formed first, so the lobe stays
    finite where bbm's ``pow(max(C_z², C_xy²), n/2)`` underflows to 0 (``n`` above about 1300 at
    ``|C| ≈ 0.58``) and bbm's value is ``0/0``."""
    c, s = jnp.cos(psi), jnp.sin(psi)
    m = jnp.maximum(jnp.abs(c), jnp.abs(s))
    d = c * (wi[..., 0] * wo[..., 0] + wi[..., 1] * wo[..., 1]) + s * wi[..., 2] * wo[..., 2]
    return jnp.where(_vis(wi, wo), cosine_lobe(d / m, exponent), 0.0)


# -- the models ---------------------------------------------------------------------------------
def _ngan_cook_torrance(p, wi, wo):
    spec = cook_torrance(Beckmann(p["alpha"]), partial(schlick, p["f0"]), wi, wo)
    return lambert(p["diffuse"], wi, wo) + p["specular"] * spec


def _low_cook_torrance(p, wi, wo):
    # bbm's beckmann<…, Normalize=false>: D without its 1/π, so π times the normalised lobe
    spec = cook_torrance(Beckmann(p["alpha"]), partial(dielectric, p["eta"]), wi, wo)
    return lambert(p["diffuse"], wi, wo) + (jnp.pi * p["specular"]) * spec


def _ngan_ashikhmin_shirley(p, wi, wo):
    spec = ashikhmin_shirley(p["exponent"], partial(schlick, p["f0"]), wi, wo)
    return lambert(p["diffuse"], wi, wo) + p["specular"] * spec


def _low_ashikhmin_shirley(p, wi, wo):
    spec = ashikhmin_shirley(p["exponent"], partial(dielectric, p["eta"]), wi, wo)
    return lambert(p["diffuse"], wi, wo) + p["specular"] * spec


def _ward(p, wi, wo, duer=False):
    return lambert(p["diffuse"], wi, wo) + p["specular"] * ward(p["alpha"], wi, wo, duer)[..., None]


def _ngan_blinn_phong(p, wi, wo):
    return lambert(p["diffuse"], wi, wo) + p["specular"] * phong(p["exponent"], wi, wo)[..., None]


def _lafortune(lobes):
    """``fn`` of Lambert plus ``lobes`` Lafortune lobes; one lobe's names carry no suffix."""
    suffixes = [""] if lobes == 1 else [f"_{k}" for k in range(1, lobes + 1)]

    def fn(p, wi, wo):
        out = lambert(p["diffuse"], wi, wo)
        for k in suffixes:
            lobe = lafortune_lobe(p["psi" + k], p["exponent" + k], wi, wo)
            out = out + p["specular" + k] * lobe[..., None]
        return out

    return fn


# -- data-driven starts ---------------------------------------------------------------------------
# The features (brdffit.fitting.start.Features) give the peak's excess ``H`` over the diffuse
# level and a GGX roughness α from its half width. Each hook turns α into the lobe's own width
# (Beckmann α_b = BECKMANN_PER_GGX α; (n·h)ⁿ ≈ e^{−nθ_h²/2}, so n = 2/α_b² for Ashikhmin–Shirley;
# the Phong lobe about the mirror direction has θ = 2θ_h, so n = 1/(2α_b²)) and solves the lobe's
# value at normal incidence for k_s. Conventions for the solver, not formulas of the sources.
def _peak(features):
    return np.maximum(np.asarray(features.height, float), 1e-6)


def _ks(value):
    """A start of ``specular`` inside its bounds (a wide lobe on a bright peak asks for more)."""
    return np.clip(value, 1e-4, SPECULAR.upper)


def _alpha_b(features):
    return float(np.clip(BECKMANN_PER_GGX * features.alpha, 2e-3, 1.0))


def _f0(features):
    return float(np.clip(np.mean(features.f0), 0.02, 0.9))


def start_ngan_cook_torrance(features) -> dict:
    """``f_s(0) = k_s F0/(π² α²)``."""
    a, f0 = _alpha_b(features), _f0(features)
    return {"diffuse": features.diffuse, "alpha": a, "f0": f0,
            "specular": _ks(_peak(features) * np.pi**2 * a * a / f0)}


def start_low_cook_torrance(features) -> dict:
    """``f_s(0) = k_s F(η, 1)/(π α²)``, ``F(η, 1) = F0``."""
    a, f0 = _alpha_b(features), _f0(features)
    return {"diffuse": features.diffuse, "alpha": a, "eta": float(ior_from_f0(f0)),
            "specular": _ks(_peak(features) * np.pi * a * a / f0)}


def _start_ashikhmin_shirley(features, fresnel: str) -> dict:
    """``f_s(0) = k_s (n + 1) F0/(8π)``."""
    a, f0 = _alpha_b(features), _f0(features)
    n = 2.0 / a**2
    out = {"diffuse": features.diffuse, "exponent": n,
           "specular": _ks(_peak(features) * 8.0 * np.pi / ((n + 1.0) * f0))}
    out.update({"f0": f0} if fresnel == "f0" else {"eta": float(ior_from_f0(f0))})
    return out


def start_ward(features) -> dict:
    """``f_s(0) = k_s/(4π α²)``."""
    a = _alpha_b(features)
    return {"diffuse": features.diffuse, "alpha": a, "specular": _ks(_peak(features) * 4.0 * np.pi * a * a)}


#: ``ψ`` of the Lafortune lobe about the mirror direction, ``(C_xy, C_z) ∝ (−1, 1)``.
MIRROR = 0.75 * np.pi
#: An added (broad) lobe's start: just past the mirror direction towards grazing, where Ngan's
#: fits all lie (``|C_xy| ≥ C_z``), off the kink of the normalisation ``max(|C_xy|, |C_z|)ⁿ``
#: at ``3π/4`` that the first lobe starts on.
PSI_START = 0.77 * np.pi


def start_phong(features, suffix: str = "") -> dict:
    """``f_s(0) = k_s (n + 2)/(2π)``, the lobe about the mirror direction (``ψ = 3π/4``)."""
    n = 0.5 / _alpha_b(features) ** 2
    return {"diffuse": features.diffuse, "exponent" + suffix: n, "psi" + suffix: MIRROR,
            "specular" + suffix: _ks(_peak(features) * 2.0 * np.pi / (n + 2.0))}


#: The starts of an added Lafortune lobe: this share of the fitted lobe's ``k_s`` ...
ADDED_SHARE = 0.1
#: ... in a lobe eight times broader than the broadest fitted one (the haze around a peak),
#: and in a broad lobe of this exponent about the mirror direction and towards grazing
#: (:data:`GRAZING_PSI`).
HAZE, BROAD_EXPONENT, GRAZING_PSI = 1 / 8, 2.0, 0.95 * np.pi


def _added_lobes(params, lobes: int) -> list[dict]:
    """The starts of a ``lobes``-lobe Lafortune from a fitted one with one lobe fewer
    (``params``): the fitted lobes unchanged beside a new lobe with ``ADDED_SHARE`` of the first
    lobe's ``k_s``, in three places the data may want it: ``HAZE`` times the exponent of the
    broadest fitted lobe (eight times broader: the haze around a peak), and broad
    (``BROAD_EXPONENT``) about the mirror direction and towards grazing (``GRAZING_PSI``). The
    fit scans them on a sample of the cells and goes on from the best
    (:meth:`brdffit.fitting.stages.Run.scan`). From the haze alone a new
    lobe the data do not want there can stay where it started (the simpler optimum with a
    faint lobe is nearly stationary) or crawl towards its place for dozens of full-table
    steps."""
    old = [""] if lobes == 2 else [f"_{k}" for k in range(1, lobes)]
    start = {"diffuse": params["diffuse"]}
    for k, o in enumerate(old, 1):
        start.update({f"specular_{k}": params["specular" + o], f"psi_{k}": params["psi" + o],
                      f"exponent_{k}": params["exponent" + o]})
    n = float(np.min([params["exponent" + o] for o in old]))
    new = f"_{lobes}"
    ks = ADDED_SHARE * np.asarray(params["specular" + old[0]])
    places = ((PSI_START, max(LAFORTUNE_MIN_EXPONENT, n * HAZE)), (PSI_START, BROAD_EXPONENT),
              (GRAZING_PSI, BROAD_EXPONENT))
    return [{**start, "specular" + new: ks, "psi" + new: psi, "exponent" + new: exponent}
            for psi, exponent in places]


def start_lafortune(features, lobes: int) -> dict:
    """Lobe 1 as :func:`start_phong`; each further lobe ``HAZE`` times as sharp as the one
    before (exponent ``n/8``, ``n/64``) with ``ADDED_SHARE`` of its ``k_s``: the start of a
    many-lobe fit that is itself the base of another (``lafortune-2`` under ``lafortune-3``)."""
    first = start_phong(features, "_1")
    out = dict(first)
    for k in range(2, lobes + 1):
        out.update({f"specular_{k}": ADDED_SHARE * np.asarray(first["specular_1"]),
                    f"psi_{k}": PSI_START,
                    f"exponent_{k}": max(LAFORTUNE_MIN_EXPONENT,
                                         first["exponent_1"] * HAZE ** (k - 1))})
    return out


# -- registration ---------------------------------------------------------------------------------
def _register(name, description, params, fn, reference, start=None, refines=None):
    return register(Model(name=name, description=description, params=params, fn=fn,
                          reference=reference, start=start, refines=refines))


NGAN = "Ngan, Durand & Matusik 2005"
LOW = "Löw, Kronander, Ynnerman & Unger 2012"

_register("ngan-cooktorrance",
          "Lambert + Cook–Torrance as Ngan 2005 fits it: Beckmann D, V-groove G, Schlick F (F0), "
          "k_s D G F/(π cosθi cosθo)",
          (DIFFUSE, SPECULAR, F0, ALPHA), _ngan_cook_torrance,
          f"{NGAN}; Cook & Torrance 1982; bbm include/bsdfmodel/ngan.h (ngancooktorrance)",
          start_ngan_cook_torrance)
_register("low-cooktorrance",
          "Lambert + Cook–Torrance as Löw 2012 fits it: Beckmann D without 1/π, V-groove G, "
          "dielectric Fresnel F(η), k_s D G F/(π cosθi cosθo)",
          (DIFFUSE, SPECULAR, ETA, ALPHA), _low_cook_torrance,
          f"{LOW}; Cook & Torrance 1982; bbm include/bsdfmodel/low.h, cooktorrance.h",
          start_low_cook_torrance)
_register("ngan-ashikhmin-shirley",
          "Lambert + the isotropic Ashikhmin–Shirley specular lobe with Schlick F (F0), as Ngan 2005",
          (DIFFUSE, SPECULAR, F0, EXPONENT), _ngan_ashikhmin_shirley,
          f"{NGAN}; Ashikhmin & Shirley 2000 eq. 4; bbm include/bsdfmodel/ngan.h, ashikhminshirley.h",
          partial(_start_ashikhmin_shirley, fresnel="f0"))
_register("low-ashikhmin-shirley",
          "Lambert + the isotropic Ashikhmin–Shirley specular lobe with dielectric Fresnel F(η), "
          "as Löw 2012",
          (DIFFUSE, SPECULAR, ETA, EXPONENT), _low_ashikhmin_shirley,
          f"{LOW}; Ashikhmin & Shirley 2000 eq. 4; bbm include/bsdfmodel/low.h, ashikhminshirley.h",
          partial(_start_ashikhmin_shirley, fresnel="eta"))
WARD_ALPHA = Param("alpha", (), 1e-3, 1.0, 0.1, "Ward roughness α (bbm's roughness)", log=True)
_register("ward", "Lambert + isotropic Ward: k_s exp(−tan²θh/α²)/(4πα² √(cosθi cosθo))",
          (DIFFUSE, SPECULAR, WARD_ALPHA), _ward,
          f"Ward 1992; {NGAN}; bbm include/bsdfmodel/ward.h", start_ward)
_register("ward-duer", "Lambert + isotropic Ward–Dür: k_s exp(−tan²θh/α²)/(4πα² cosθi cosθo)",
          (DIFFUSE, SPECULAR, WARD_ALPHA), partial(_ward, duer=True),
          f"Dür 2006; {NGAN}; bbm include/bsdfmodel/wardduer.h", start_ward)
PHONG_EXPONENT = Param("exponent", (), 0.5, 1e6, 100.0, "Phong exponent n (bbm's sharpness)", log=True)
_register("ngan-blinn-phong",
          "Lambert + Ngan 2005's Blinn–Phong as bbm defines it: the modified Phong lobe "
          "k_s (n+2)/(2π) max(0, R(ωi)·ωo)ⁿ about the mirror direction",
          (DIFFUSE, SPECULAR, PHONG_EXPONENT), _ngan_blinn_phong,
          f"{NGAN}; Lafortune & Willems 1994; bbm include/bsdfmodel/ngan.h, phong.h",
          lambda features: {k: v for k, v in start_phong(features).items() if k != "psi"})


#: ``ψ`` up to ``π`` (``C_z ≥ 0``, as in every published fit). With ``C_z < 0`` allowed (up to
#: ``5π/4``) the fabrics' fits ran on to that bound too, in 30–60 steps instead of 3–6.
PSI_MAX = float(np.pi)
#: The Lafortune lobe's exponent from 1 (a cosine lobe): below it the residuals lose their
#: derivative in ``ψ`` at the lobe's edge, ``∂/∂ψ max(0, d)ⁿ = n dⁿ⁻¹ ∂d/∂ψ → ∞`` as
#: ``d → 0⁺``, so no quadratic model holds near a lobe whose edge crosses the cells, and a
#: faint broad lobe crawls there (every published fit has ``n ≥ 2.29``). The modified Phong
#: lobe of ``ngan-blinn-phong`` keeps 0.5: no parameter of it moves the lobe's edge.
LAFORTUNE_MIN_EXPONENT = 1.0


def _lafortune_params(lobes):
    """The parameters of a ``lobes``-lobe Lafortune. By default lobe ``k`` has the exponent
    ``100 · HAZE^(k−1)`` (100, 12.5, 1.56: each eight times broader than the one before, the
    haze of :func:`start_lafortune`): identical default lobes would be one lobe whose ``k_s``
    the data cannot split among them (a file written at the defaults would fit ambiguously)."""
    params = [DIFFUSE]
    for i, k in enumerate([""] if lobes == 1 else [f"_{k}" for k in range(1, lobes + 1)]):
        which = "" if not k else f" of lobe {k[1:]}"
        params += [
            Param("specular" + k, (3,), 0.0, 4.0, 0.1, f"specular scale k_s (RGB){which}",
                  per_channel=True),
            Param("psi" + k, (), 0.0, PSI_MAX, MIRROR,
                  f"direction ψ of (C_xy, C_z) = (cos ψ, sin ψ){which}: 3π/4 the mirror lobe"),
            Param("exponent" + k, (), LAFORTUNE_MIN_EXPONENT, 1e6, 100.0 * HAZE ** i,
                  f"exponent n{which} (bbm's sharpness)", log=True),
        ]
    return tuple(params)


_register("lafortune",
          "Lambert + one Lafortune lobe with Ngan 2005's normalisation; (C_xy, C_z) = (cos ψ, sin ψ)",
          _lafortune_params(1), _lafortune(1),
          f"Lafortune et al. 1997 eq. 4; {NGAN}; bbm include/bsdfmodel/ngan.h, lafortune.h",
          start_phong)
_register("lafortune-2", "Lambert + two Lafortune lobes with Ngan 2005's normalisation",
          _lafortune_params(2), _lafortune(2),
          f"Lafortune et al. 1997 eq. 4; {NGAN}", partial(start_lafortune, lobes=2),
          refines=("lafortune", partial(_added_lobes, lobes=2)))
_register("lafortune-3", "Lambert + three Lafortune lobes with Ngan 2005's normalisation",
          _lafortune_params(3), _lafortune(3),
          f"Lafortune et al. 1997 eq. 4; {NGAN}", partial(start_lafortune, lobes=3),
          refines=("lafortune-2", partial(_added_lobes, lobes=3)))


# -- the published forms ------------------------------------------------------------------------
def _scalar(value) -> float:
    return float(np.asarray(value, float).reshape(-1)[0])


def _common(fit) -> dict:
    return {"diffuse": fit.albedo, "specular": np.asarray(fit.params["albedo"], float)}


def _form(bbm_class, model, study, **names):
    """A form whose parameters are bbm's, renamed (``ours="bbm's"``)."""
    def to_params(fit):
        return {**_common(fit), **{k: _scalar(fit.params[v]) for k, v in names.items()}}

    register_published(PublishedForm(bbm_class, model, to_params, study))


def _lafortune_form(fit) -> dict:
    cxy, cz = _scalar(fit.params["Cxy"]), _scalar(fit.params["Cz"])
    return {**_common(fit), "psi": float(np.arctan2(cz, cxy)),
            "exponent": _scalar(fit.params["sharpness"])}


_form("NganCookTorrance", "ngan-cooktorrance", "Ngan 2005", f0="eta", alpha="roughness")
_form("LowCookTorrance", "low-cooktorrance", "Löw 2012", eta="eta", alpha="roughness")
_form("NganAshikhminShirley", "ngan-ashikhmin-shirley", "Ngan 2005", f0="fresnelReflectance",
      exponent="sharpness")
_form("LowAshikhminShirley", "low-ashikhmin-shirley", "Löw 2012", eta="fresnelReflectance",
      exponent="sharpness")
_form("NganWard", "ward", "Ngan 2005", alpha="roughness")
_form("NganWardDuer", "ward-duer", "Ngan 2005", alpha="roughness")
_form("NganBlinnPhong", "ngan-blinn-phong", "Ngan 2005", exponent="sharpness")
register_published(PublishedForm("NganLafortune", "lafortune", _lafortune_form, "Ngan 2005"))
