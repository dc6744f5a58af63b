"""The seed paper's equations as printed, and as the code uses them (DESIGN.md section 1)."""

ERRATA = [
    {
        "seed": "chi_b = Gamma (sin phi0 - sin phi) + Gamma cos phi0 (phi - phi0)"
        " + (phi - phi0)^2 / 2",
        "corrected": "chi_b - chi_p = Gamma (sin phi0 - sin phi) + Gamma cos phi0 (phi - phi0)"
        " - (phi - phi0)^2 / 2",
        "note": "seed eq. 5: this is the height above the plate, not the ball's position, and "
        "gravity pulls down: the quadratic term is negative.",
    },
    {
        "seed": "chi_b(t) = Gamma sin phi >= 1",
        "corrected": "Gamma sin phi > 1   (with friction: Gamma sin phi > 1 + mu, plate moving up)",
        "note": "seed eq. 6: the takeoff condition is on the plate's acceleration, -chi_p'' = "
        "Gamma sin phi exceeding gravity, not on a position; in the (phi, chi) plane it is the "
        "line chi_p = 1.",
    },
    {
        "seed": "F = T^2/2 + Gamma cos phi0 (T + cos T) - Gamma sin phi0 (1 - sin t) = 0",
        "corrected": "Gamma sin phi0 + Gamma cos phi0 T - T^2/2 - Gamma sin(phi0 + T) = 0,"
        " first root T > 0",
        "note": "seed eq. 8 is garbled: the flight ends when the ball's height equals the plate's.",
    },
    {
        "seed": "(friction not written)",
        "corrected": "chi_b'' = -(1 + mu) while rising, -(1 - mu) while falling (lab frame)",
        "note": "Coulomb friction on the guide, mu a fraction of the weight: a flight is two "
        "parabolas joined at the apex.",
    },
]
