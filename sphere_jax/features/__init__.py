"""Local features by name: hand-crafted descriptors (SHOT, FPFH, Spin Images, USC) and LRFs
(SHOT, TOLDI, 3DSN, FLARE) on exact radius neighbourhoods, the learned ones from the shipped
bundles, and the pair vote's two descriptors.

================  ============================================================================
``neighbourhood``  exact radius neighbourhoods as ragged arrays
``descriptors``    SHOT, Spin Images, USC (numpy), FPFH (open3d)
``lrfs``           SHOT, TOLDI and 3DSN frames
``registry``       every method's name (``descriptor[@frame][+procedure]``), key and needs
``methods``        every descriptor and LRF built from its name
``voted``          ``lead@compass+vote`` and ``shot+vote`` for :mod:`sphere_jax.registration.vote`
================  ============================================================================
"""
