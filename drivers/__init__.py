"""Instrument drivers (robots, force/torque sensors, trackers, loads) and simulated fakes."""
