"""Energy-conserving terms built on a precomputed directional-albedo table.

:mod:`.albedo_table` (``E₀, E₁`` of a microfacet lobe over roughness and elevation, built once
and cached), :mod:`.multiscatter` (the Imageworks / Kulla–Conty multiple-scattering lobe, RTR
eqs. 9.56–9.60) and :mod:`.coupled_diffuse` (the Kelemen / Ashikhmin–Shirley diffuse coupled to
the specular albedo, RTR eq. 9.65). The modules are imported by name (``albedo_table`` is both
a module and its function, so this package re-exports nothing).
"""
