"""Evaluations (numpy side): registration and LRF repeatability on 3DMatch-layout scenes."""
