"""bouncelab: a mass bouncing on a vibrating plate, from raw recordings to a diagnosed model.

Packages, one concept each:

- :mod:`bouncelab.physics`  the event-driven impact map and its model variants (nondimensional)
- :mod:`bouncelab.runs`     raw run folders: ``run.yaml``, recordings, validation
- :mod:`bouncelab.rig`      the virtual rig, a dimensional time-stepped simulator of the lab
- :mod:`bouncelab.flights`  flight times from continuity (and accelerometer) signals
- :mod:`bouncelab.calibration`  friction and restitution from drop tests
- :mod:`bouncelab.gap`      the sim-to-real gap: distances, regions, effect attribution
- :mod:`bouncelab.figures`  one module per figure, each a function from data to a Figure
- :mod:`bouncelab.cli`      the ``bouncelab`` command, one module per subcommand
"""

__version__ = "0.1.0"
