"""The real-time half of irl: executive, components, supervisor FSM, VM, motion.

Importing this package imports nothing else: ``irl check`` goes through
``runtime.cli.main`` and must start without NumPy or ZeroMQ.
"""
