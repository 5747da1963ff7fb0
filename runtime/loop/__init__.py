"""The loop process: the cyclic executive, the supervisor FSM, the components, the VM, one robot
assembled (:mod:`runtime.loop.system`) and the process that runs it (:mod:`runtime.loop.robotloop`).
"""
