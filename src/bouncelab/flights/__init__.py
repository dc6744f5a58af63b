"""Flight extraction from the continuity channel, drive phase, QC; the accelerometer method.

>>> from bouncelab.flights import extract_run, detect_contacts
>>> flights, qc = extract_run("raw/sweep_g0-4")     # doctest: +SKIP

docs/flights.md describes the algorithm, its rules and limits.
"""

from bouncelab.flights.detect import Detection, NoContactsError, detect_contacts
from bouncelab.flights.extract import (
    FLIGHT_COLUMNS,
    QC_COLUMNS,
    extract_run,
    flights_from_detection,
    qc_path_for,
)
from bouncelab.flights.phase import SineFit, fit_sine, phase_at

__all__ = [
    "FLIGHT_COLUMNS",
    "QC_COLUMNS",
    "Detection",
    "NoContactsError",
    "SineFit",
    "detect_contacts",
    "extract_run",
    "fit_sine",
    "flights_from_detection",
    "phase_at",
    "qc_path_for",
]
