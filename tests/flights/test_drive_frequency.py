"""The drive channel's own frequency (``bouncelab.flights.phase.dominant_frequency``) and
the warning when run.yaml states another (``drive_frequency_warning``, and its use by the
diagnosis). References: the frequencies the test signals are made with."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from bouncelab.flights.phase import (
    DRIVE_FREQUENCY_TOLERANCE,
    dominant_frequency,
    drive_frequency_warning,
)
from bouncelab.gap.diagnose import drive_warnings

FS = 20_000.0


@pytest.mark.parametrize("freq_hz", [30.0, 29.37, 61.2])
def test_a_noisy_sine_with_a_harmonic_gives_its_frequency(freq_hz):
    """1.5 s of a sine (between bins for 29.37 and 61.2 Hz), 5 % noise, a 10 % second
    harmonic and an offset: within 0.005 Hz, a tenth of the warning's tolerance at 30 Hz
    (0.2 %, 0.06 Hz)."""
    t = np.arange(int(1.5 * FS)) / FS
    rng = np.random.default_rng(1)
    w = 2 * np.pi * freq_hz * t
    y = 0.2 + np.sin(w + 0.3) + 0.1 * np.sin(2 * w) + 0.05 * rng.standard_normal(t.size)
    assert dominant_frequency(y, FS) == pytest.approx(freq_hz, abs=0.005)


@pytest.mark.parametrize("cycles", [8.3, 20.5, 60.25])
def test_a_clean_sine_of_few_cycles_is_read_to_a_ten_thousandth(cycles):
    """Grandke's ratio on a Hann window (reference: the sine's own frequency), for every
    offset from a bin: within 0.01 % of the frequency over 8.3 cycles and better over
    more, where a log-parabola through three bins was 0.19 % off."""
    fs = 2000.0
    for f in 25.0 + np.linspace(0.0, 1.0, 21):
        n = int(round(cycles / f * fs))
        y = np.sin(2 * np.pi * f * np.arange(n) / fs + 0.7)
        assert dominant_frequency(y, fs) == pytest.approx(f, rel=1e-4)


def test_noise_alone_or_too_few_samples_give_nan():
    rng = np.random.default_rng(2)
    assert np.isnan(dominant_frequency(rng.standard_normal(30_000), FS))
    assert np.isnan(dominant_frequency(np.ones(10), FS))


def test_the_warning_speaks_only_beyond_the_tolerance():
    inside = 30.0 * (1.0 + 0.8 * DRIVE_FREQUENCY_TOLERANCE)
    assert drive_frequency_warning(np.array([inside, np.nan]), 30.0) is None
    assert drive_frequency_warning(np.array([np.nan, np.nan]), 30.0) is None
    text = drive_frequency_warning(np.array([25.0, 25.0, np.nan]), 30.0, "raw/x/run.yaml")
    assert text.startswith("raw/x/run.yaml: the drive channel runs at 25.000 Hz")
    assert "(median over 2 steps), -16.7 % from drive_frequency_hz 30" in text


def test_the_diagnosis_warns_from_the_qc_table_and_keeps_quiet_without_one():
    run = SimpleNamespace(drive_frequency_hz=29.0, yaml_path=Path("raw/r/run.yaml"))
    qc = pd.DataFrame({"drive_frequency_hz": [np.nan, 30.0, 30.0001]})
    (warning,) = drive_warnings(run, qc)
    assert "raw/r/run.yaml: the drive channel runs at 30.000 Hz" in warning
    assert drive_warnings(run, None) == []
    assert drive_warnings(run, qc.rename(columns={"drive_frequency_hz": "x"})) == []
    assert drive_warnings(SimpleNamespace(drive_frequency_hz=30.0, yaml_path=""), qc) == []
