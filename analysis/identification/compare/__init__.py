"""Two campaigns compared: results read back (load), the test of a change (comparison), its
plot.
"""
