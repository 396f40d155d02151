"""A robot made ready to run.

The shipped robots, a ``[robot]`` table built into a model, and its home posture, checked against
its joints' limits, its efforts and its footprint.
"""
