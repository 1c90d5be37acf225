"""Generators of the embedded synthetic data, written in the real datasets' layouts so that
the readers of :mod:`sphere_jax.data.readers` read them back (no download, same seed → same
bytes).

===================  =========================================================================
:mod:`.synthetic`    rooms fused into 3DMatch-layout fragments, a ModelNet-layout shape set,
                     labelled RGB-D table tops; the default data cache
:mod:`.camera`       a virtual RGB-D camera with a Kinect-like error model
:mod:`.shapes`       procedural meshes: object classes and room furniture
:mod:`.washington`   object crops in the Washington RGB-D Object layout
===================  =========================================================================
"""
