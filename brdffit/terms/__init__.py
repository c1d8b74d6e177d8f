"""The physics pieces models are composed from: pure ``jnp`` functions, one idea per module.

* :mod:`._math`: the shading-frame conventions (``z`` is the normal, ``wi``, ``wo``, ``wm``) and
  the gradient-safe primitives every term uses;
* :mod:`.ndf`: normal distribution functions, one module per family, each giving ``D`` and ``Λ``;
* :mod:`.masking`: ``G1`` and every ``G2`` form, from an NDF's ``Λ``;
* :mod:`.fresnel`: Fresnel terms (Schlick, dielectric, conductor);
* :mod:`.diffuse`: closed-form diffuse lobes (Lambert, Burley, Oren–Nayar, Shirley, Hammon);
* :mod:`.microfacet`: the microfacet specular lobe composed from an NDF, a ``G2`` form and a
  Fresnel term;
* :mod:`.energy`: terms that read a precomputed albedo table (the table, multiple scattering,
  the coupled diffuse);
* :mod:`.aps`: the pieces of the Ashikhmin–Premože–Shirley generator (any ``p(h)``).

The pieces come in ranks: ``_math``; then ``ndf``, ``masking``, ``fresnel``; then ``diffuse``,
``microfacet``; then ``energy``, ``aps``. A piece imports only pieces of a lower rank, and
nothing here imports :mod:`brdffit.models` or anything above it (``tests/test_layers.py``
checks both). The pieces are imported where they are used; this package loads none of them.
"""
