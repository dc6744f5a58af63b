"""Nondimensional event-driven impact map of a body on a vibrating plate.

Units (the seed paper's): phase ``phi = omega t`` (rad), height ``chi = x omega^2 / g``,
velocity in ``g / omega``, Gamma ``= A omega^2 / g``, energies per unit mass in
``(g / omega)^2``.  See docs/physics.md for the equations, the landing solver and the
protocols.
"""

from bouncelab.physics.model import (
    EFFECT_ORDER,
    EFFECTS,
    Model,
    parse_assignments,
    rigid_plate_restitution,
    two_body_restitution,
)
from bouncelab.physics.simulate import (
    FLIGHT_COLUMNS,
    simulate_drop,
    simulate_from,
    simulate_grid,
    simulate_protocol,
)

__all__ = [
    "EFFECTS",
    "EFFECT_ORDER",
    "FLIGHT_COLUMNS",
    "Model",
    "parse_assignments",
    "rigid_plate_restitution",
    "simulate_drop",
    "simulate_from",
    "simulate_grid",
    "simulate_protocol",
    "two_body_restitution",
]
