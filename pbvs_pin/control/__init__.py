"""Control laws: passivity-based kinematic controller, secondary objectives, dynamic
compensation, and a classic IBVS baseline."""
