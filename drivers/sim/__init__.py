"""The simulated lab: one seeded world shared by fake instruments speaking real wire protocols.

Start it programmatically with :class:`drivers.sim.lab.Lab`, or from the shell
with ``campaign lab --fake``.
"""
