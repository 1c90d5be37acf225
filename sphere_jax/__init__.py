"""sphere_jax — learned, rotation-equivariant 3D local features in JAX.

Compass (a learned local reference frame), LEAD / LEAD-PN (unsupervised descriptors) and SOUND
(a self-orienting descriptor) on spherical CNNs, with the registration, LRF and recognition
evaluations of the thesis they come from.

The three calls most people need::

    import sphere_jax
    frames = sphere_jax.orient("compass", points, keypoints)        # [K, 3, 3], shipped Compass
    desc = sphere_jax.describe("lead", points, keypoints, frames=frames,
                               whiten="compass")      # [K, 512], whitened for Compass frames
    bundle = sphere_jax.load_bundle(path)    # a bundle folder (or kind), reused across calls

Conventions (``sphere_jax/spherical/CONVENTIONS.md``): points are ``[N, 3]`` float arrays in metres,
rotations act actively (``p' = R p``), an LRF is a 3×3 matrix whose **columns** are x̂, ŷ, ẑ in
world coordinates, so a patch in canonical pose is ``(p − keypoint) @ F``. Modules:
``so3, wigner, transforms, correlation, layers, signal, soft_argmax, losses`` (the spherical
core, pure functions), ``models`` (flax), ``bundles`` (trained networks: files, cards,
whitenings, inference), ``training``, ``data`` (readers, patches, synthetic data) and
``eval`` (benchmarks).
"""
from __future__ import annotations

__all__ = ["load_bundle", "orient", "describe", "register", "SphereJaxError"]

from sphere_jax.checks import SphereJaxError


def load_bundle(path):
    """Load an inference bundle (``bundle/`` written at the end of training): an
    :class:`sphere_jax.bundles.inference.Bundle` with ``.orient``, ``.describe`` and ``.config``."""
    from sphere_jax.bundles import inference
    return inference.load_bundle(path)


def _bundle(bundle_or_path):
    from sphere_jax import checks
    from sphere_jax.bundles import inference
    if isinstance(bundle_or_path, (str, bytes)) or hasattr(bundle_or_path, "__fspath__"):
        return inference.cached_bundle(bundle_or_path)
    if not isinstance(bundle_or_path, inference.Bundle):
        raise checks.InputError("bundle", "a Bundle, a bundle folder or a shipped model kind "
                                "('compass', 'lead', 'lead_pn', 'sound')",
                                checks.shown(bundle_or_path))
    return bundle_or_path


def orient(bundle, points, keypoints, radius=None, chunk=None, seed=0, workers=None,
           on_invalid="raise"):
    """Local reference frames from a Compass or SOUND bundle.

    Args:
      bundle: a :class:`sphere_jax.bundles.inference.Bundle`, the path of one (loaded once, then
        cached) or a shipped model kind (``"compass"``, ``"sound"``).
      points: ``[N, 3]`` float cloud, metres (e.g. voxelised at 2 cm for 3DMatch), or an open3d
        point cloud (``open3d.geometry.PointCloud`` or ``open3d.t.geometry.PointCloud``).
      keypoints: ``[K]`` int indices into ``points`` or ``[K, 3]`` coordinates.
      radius: support radius in metres (default: the bundle's training radius, 0.3 m).
      chunk: patches per jitted, vmapped call (default: the bundle's ``infer_chunk``); memory
        stays bounded for any K and the function compiles once.
      workers: chunks run at a time (default: one per core, at most 4; see
        :func:`sphere_jax.parallel.run_chunked`); memory grows with it.
      seed: seed of the patch resampling (N points drawn evenly from each support from one
        random offset: ``sphere_jax.data.supports.DRAW``).
      on_invalid: a keypoint whose support holds fewer than the bundle's ``min_support``
        points (16) cannot be oriented: ``"raise"`` (default) raises an error saying which;
        ``"mask"`` returns ``(frames, valid)``, their frames NaN and ``valid [K]`` False.

    Returns:
      ``[K, 3, 3]`` float32 rotation matrices, columns x̂, ŷ, ẑ in world coordinates.

    Raises:
      sphere_jax.SphereJaxError: a ``ValueError`` naming the argument that was wrong.
    """
    return _bundle(bundle).orient(points, keypoints, radius=radius, chunk=chunk, seed=seed,
                                  workers=workers, on_invalid=on_invalid)


def describe(bundle, points, keypoints, radius=None, chunk=None, seed=0, frames=None,
             workers=None, on_invalid="raise", as_open3d=False, whiten="auto"):
    """Rotation-invariant local descriptors from a LEAD, LEAD-PN or SOUND bundle.

    LEAD's SO(3) descriptor is turned to canonical pose by ``frames`` (``[K, 3, 3]``, e.g.
    :func:`orient` with a Compass bundle) or, by default, FLARE; LEAD-PN describes the
    FLARE-oriented patch; SOUND orients itself.

    Args:
      bundle: a :class:`sphere_jax.bundles.inference.Bundle`, the path of one, or a shipped model
        kind (``"lead"``, ``"lead_pn"``, ``"sound"``).
      points: ``[N, 3]`` float cloud, metres, or an open3d point cloud.
      keypoints: ``[K]`` int indices into ``points`` or ``[K, 3]`` coordinates.
      radius: support radius in metres (default: the bundle's).
      chunk, seed, workers, on_invalid: as in :func:`orient`.
      frames: optional LRFs for LEAD (rotations: orthonormal, det +1, within 1e-3).
      whiten: the bundle's descriptor whitening, fitted on its training scans
        (:mod:`sphere_jax.bundles.whitening`): ``"auto"`` the one for its own frames when
        ``frames`` is None (none when frames are given), ``"compass"`` LEAD's for Compass
        frames, None the network's raw output.
      as_open3d: return an ``open3d.pipelines.registration.Feature`` (``data [D, K]``), which
        open3d's ``registration_ransac_based_on_feature_matching`` and FGR take directly.

    Returns:
      ``[K, D]`` float32 descriptors (D = 512 for the shipped bundles; unit length when
      whitened); compare them with the Euclidean distance (e.g. mutual nearest neighbours,
      :func:`sphere_jax.registration.mutual_matches`).
    """
    return _bundle(bundle).describe(points, keypoints, radius=radius, chunk=chunk, seed=seed,
                                    frames=frames, workers=workers, on_invalid=on_invalid,
                                    as_open3d=as_open3d, whiten=whiten)


def register(source, target, method=None, voxel="auto", radius="auto", n_keypoints=None,
             seed=0, bundle=None, icp=True, adapt=None, adapt_workdir=None, progressive=True,
             **limits):
    """Register ``source`` onto ``target`` (``[N, 3]`` arrays, open3d clouds or file paths):
    voxel grid → keypoints → descriptors → mutual matches → RANSAC → point-to-plane ICP.

    ``method``: a name of :mod:`sphere_jax.features.registry` (default
    :data:`sphere_jax.align.DEFAULT_METHOD`, the shipped LEAD-PN; ``lead@compass``, ``sound``,
    ``fpfh``, ``shot``, ...); ``n_keypoints`` per cloud (default
    :data:`sphere_jax.registration.pipeline.DEFAULT_KEYPOINTS`), described a random quarter,
    then half, then all (``progressive``: stopping at the first share that registers with
    confidence). ``voxel`` and ``radius`` default to a scale chosen from the clouds
    (:func:`sphere_jax.registration.scale.auto_scale`). ``adapt``: minutes of
    adaptation of the method's networks to these two scans first, without labels (kept in
    ``adapt_workdir``; two networks adapt side by side in processes of their own, so a script
    calls this under ``if __name__ == "__main__":``). ``limits``: ``min_inliers``,
    ``min_fitness`` (below them the result is a failure). Details:
    :func:`sphere_jax.align.register`.

    Returns:
      :class:`sphere_jax.registration.pipeline.Registration`: ``transform`` (4×4,
      ``p_target = T p_source``), ``inliers``, ``matches``, ``fitness``, ``rmse``, the
      ``voxel`` and ``radius`` used and the ``seconds`` of each stage, the ``keypoints``
      described; ``.summary()`` prints them.
    """
    from sphere_jax import align
    from sphere_jax.registration import pipeline
    # None, not any false value, means the default: n_keypoints=0 is refused by align.
    method = align.DEFAULT_METHOD if method is None else method
    n_keypoints = pipeline.DEFAULT_KEYPOINTS if n_keypoints is None else n_keypoints
    return align.register(source, target, method, voxel, radius, n_keypoints, seed, bundle,
                          icp, adapt=adapt, adapt_workdir=adapt_workdir,
                          progressive=progressive, **limits)
