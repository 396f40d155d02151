"""Closed-loop simulation: scenarios, targets, obstacles, laser, camera sensor, the loop."""
