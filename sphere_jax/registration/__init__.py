"""Registration as a library: prepare two scans, match their descriptors, estimate the rigid
transform that maps one onto the other.

==============  ===============================================================================
``fragments``   :class:`Fragment` — voxelised points, normals towards the sensor, keypoints
``matching``    mutual nearest neighbours in descriptor space
``estimation``  Kabsch, RANSAC on putative matches, RANSAC's consensus, point-to-plane ICP
``vote``        the pair vote: a rotation voted from matched frames, its box orbit, and
                :class:`VotedFrames`, which describes a pair again in the voted frames
``scale``       the voxel and support radius a pair is registered at, from the clouds
``pipeline``    the whole pipeline on one :class:`Settings`, keypoints share by share, and
                :class:`Registration`, the result and its status
==============  ===============================================================================

Descriptors come in as arrays or as functions of a fragment (:mod:`sphere_jax.features` makes
them by name): this layer imports neither the trained bundles nor the benchmarks.
``sphere_jax.register`` checks its inputs and chooses the method's descriptors, then runs the
pipeline; the registration benchmark
(:mod:`sphere_jax.eval.registration`) scores it against ground truth.
"""
from sphere_jax.registration.estimation import (consensus, kabsch, point_to_plane_icp, ransac,
                                                ransac_consensus)
from sphere_jax.registration.fragments import Fragment, estimate_normals, fragment
from sphere_jax.registration.matching import mutual_matches, nearest
from sphere_jax.registration.vote import VotedFrames, box_orbit, vote_rotation, vote_rotations

__all__ = ["Fragment", "VotedFrames", "box_orbit", "consensus", "estimate_normals", "fragment",
           "kabsch", "mutual_matches", "nearest", "point_to_plane_icp", "ransac",
           "ransac_consensus", "vote_rotation", "vote_rotations"]
