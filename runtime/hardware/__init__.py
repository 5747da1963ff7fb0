"""The robot's backends behind declared interfaces: the simulated arm and cell, the Modbus I/O.
"""
