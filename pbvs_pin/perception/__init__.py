"""Perception.

Camera frames, the two-sphere image features with their interaction matrix (eq. 3), the detectors
of a rendered image and the target-velocity filter (eq. 30).
"""
