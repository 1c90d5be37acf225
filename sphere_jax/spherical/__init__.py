"""The spherical-CNN core: pure JAX functions, jit/vmap/grad-able, float32 at run time with
float64 constants built once outside traced code.

===================  =============================================================================
:mod:`.so3`          rotations, Euler angles, SOFT grids, geodesic distance (owns the conventions)
:mod:`.wigner`       Wigner-d tables and quadrature weights
:mod:`.transforms`   S2 / SO(3) Fourier transforms, band-limit change, spectral rotation
:mod:`.correlation`  S2 and SO(3) correlation with kernel grids, per-degree spectral products
:mod:`.layers`       S2Conv, SO3Conv, grid batch norm (flax, thin over the functions above)
:mod:`.fused`        layers chained in the spectral domain (the fast inference path)
:mod:`.signal`       point patch -> spherical signal
:mod:`.soft_argmax`  Parzen-weighted soft arg-max of an SO(3) map -> rotation
===================  =============================================================================

Every convention (grids, Euler angles, Wigner-D, layouts, LRF columns, ground-truth
directions) and the seed's model numbers are stated in ``CONVENTIONS.md`` beside this file.
"""
