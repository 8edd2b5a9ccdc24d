"""Simulation: the dynamic track model, the simulator and its manoeuvres."""
