"""numpy/open3d adapters: dataset readers, keypoints and patches, augmentation, synthetic scans.

The JAX side (``sphere_jax`` proper) never imports this package's open3d users; everything here
returns numpy arrays.
"""
