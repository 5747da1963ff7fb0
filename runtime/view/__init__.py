"""``irl view``: the robot in 3D in a browser page, served from this process on 127.0.0.1.

Three views share one stage (:mod:`runtime.view.stage`: the arm from its URDF, its tool and
base, the specification's named frames, the program's source):

* :mod:`runtime.view.program`: a program's paths, as the offline planners plan them
  (``irl check``'s run of the program), each move named with its line, the refused ones
  marked with the reason;
* :mod:`runtime.view.replay`: a report (CSV) or a recording (MCAP) replayed, with a time
  slider, play and pause, the TCP's trace and the phases on the time line;
* :mod:`runtime.view.live`: a served robot, attached over the protocol (read-only);
* :mod:`runtime.view.pendant`: the operator's pendant of a served robot, a page of its own
  (``pendant.html``, served by :mod:`runtime.view.pagehttp`) with the 3D view in it.

The page is viser's (a three.js scene and its controls, served with the Python package,
no internet access needed): docs/runtime.md, "The 3D view", says why. Not real-time:
nothing here runs in a tick.
"""
