"""The server process of ``irl serve``: requests, jobs, control, telemetry. It talks to the loop
process only through :mod:`runtime.wire`; it does not import the loop or the planners.
"""
