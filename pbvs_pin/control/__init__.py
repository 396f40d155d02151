"""Control laws of the paper's Fig. 3.

The passivity-based kinematic controller, secondary objectives, dynamic compensation, and a
classic IBVS baseline.
"""
