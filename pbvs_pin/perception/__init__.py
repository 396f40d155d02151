"""Perception.

Camera frames, the two-sphere image features with their interaction matrix (eq. 2), the detectors
of a rendered image and the target-velocity filter (eq. 3's estimate).
"""
