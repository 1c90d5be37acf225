"""Readers of real file formats and dataset layouts (numpy out, errors naming file and line).

===================  =========================================================================
:mod:`.io`           point-cloud and mesh files: PLY, PCD, OFF, ModelNet ``.txt`` / ``.h5``
:mod:`.threedmatch`  3DMatch / 3DLoMatch / ETH scenes: fragments, ``gt.log``, ``gt.info``
:mod:`.stanford`     Stanford range scans and their ``.conf`` poses
:mod:`.rgbd`         RGB-D frames: intrinsics, poses, images, back-projection, object frames
:mod:`.washington`   the Washington RGB-D Object layout (cropped object frames)
===================  =========================================================================
"""
