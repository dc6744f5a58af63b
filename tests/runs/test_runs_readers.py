"""Round trips: a known signal written in each format is read back in volts.

References: the signal written (``known_signals``). Tolerances: exact for CSV (the
shortest repr round-trips a float64), NPZ and TDMS (binary float64); for 16-bit audio
1.5 LSB of full scale, because libsndfile writes ``round(x * 32767)`` and reads
``q / 32768`` (half an LSB of rounding plus up to one LSB from the 32767/32768 scales).
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from hypothesis import given, settings
from hypothesis import strategies as st
from runs_fixtures import DURATION_S, FORMATS, FS, STEPS, known_signals

from bouncelab.errors import BouncelabError
from bouncelab.runs import ROLES, Run, load_run, read_recording, step_table, validate_run

LSB16 = 1.0 / 32768


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_every_format(make_run, fmt):
    full_scale = 2.5 if fmt in ("flac", "wav") else 1.0
    sig = known_signals()
    if fmt in ("flac", "wav"):
        sig = {r: v * full_scale for r, v in sig.items()}
        run_dir = make_run(fmt, signals=sig, full_scale_v=full_scale)
    else:
        run_dir = make_run(fmt, signals=sig)
    rec = read_recording(load_run(run_dir))
    assert rec.fs == FS
    assert rec.n_samples == int(FS * DURATION_S)
    assert rec.duration_s == pytest.approx(DURATION_S, rel=1e-12)
    assert set(rec.channels) == set(ROLES)
    assert rec.time_s is None
    np.testing.assert_array_equal(rec.times[:3], np.arange(3) / FS)  # index / fs
    for role in ROLES:
        got = rec.channels[role]
        assert got.ndim == 1 and got.flags.c_contiguous and got.flags.writeable
        if fmt in ("flac", "wav"):
            assert got.dtype == np.float32
            np.testing.assert_allclose(got, sig[role], rtol=0, atol=1.5 * LSB16 * full_scale)
        else:
            assert got.dtype == np.float64
            np.testing.assert_array_equal(got, sig[role])


@pytest.mark.parametrize("fmt", ["flac", "wav"])
def test_audio_integer_samples_are_exact(make_run, fmt):
    """int16 samples q read back as exactly q / 32768 * full_scale_v (float32 holds it)."""
    run_dir = make_run(fmt, full_scale_v=4.0)
    q = np.arange(-32768, 32768, 8, dtype=np.int16)  # 8192 frames: all steps stay inside
    data = np.stack([q, q[::-1], -(q + 1)], axis=1)
    sf.write(run_dir / f"rec.{fmt}", data, int(FS), subtype="PCM_16")
    rec = read_recording(load_run(run_dir))
    expected = q.astype(np.float64) / 32768 * 4.0
    np.testing.assert_array_equal(rec.channels["continuity"], expected.astype(np.float32))
    np.testing.assert_array_equal(rec.channels["drive"], expected[::-1].astype(np.float32))


@pytest.mark.parametrize("fmt", ["npz", "csv"])
def test_time_column_round_trip(make_run, fmt):
    """A time_s column/array comes back as Recording.time_s; duration = last + 1/fs."""
    n = int(FS * DURATION_S)
    t = 100.0 + np.arange(n) / FS  # a lab clock that does not start at 0
    steps = [{"t_s": 100.0 + ts, "gamma": g} for ts, g in STEPS]
    run_dir = make_run(fmt, time_s=t, yaml_overrides={"gamma_steps": steps})
    rec = read_recording(run_dir)
    np.testing.assert_array_equal(rec.time_s, t)
    assert rec.t_start_s == 100.0
    assert rec.duration_s == pytest.approx(100.0 + DURATION_S, rel=1e-12)
    assert rec.times is rec.time_s
    # validate's JSON: the length as duration_s (it said 100 s too long), the end apart
    doc = validate_run(run_dir).to_dict()
    assert doc["duration_s"] == pytest.approx(DURATION_S, rel=1e-9)
    assert doc["t_end_s"] == pytest.approx(100.0 + DURATION_S, rel=1e-12)
    assert "time_s" not in rec.channels


@pytest.mark.parametrize("decimals", [2, 3])
def test_rounded_time_column_reads_as_the_regular_axis(make_run, decimals, caplog):
    """A time_s printed with too few digits (LabVIEW's %.3f: consecutive samples share a
    millisecond) is read as first time + index / fs, with a warning; the flights then
    sit where the samples are, not on the rounding's staircase."""
    n = int(FS * DURATION_S)
    exact = 100.0 + np.arange(n) / FS
    t = np.round(exact, decimals)
    assert (np.diff(t) == 0).any()  # the case: ties
    steps = [{"t_s": 100.0 + ts, "gamma": g} for ts, g in STEPS]
    run_dir = make_run("csv", time_s=t, yaml_overrides={"gamma_steps": steps})
    with caplog.at_level("WARNING"):
        rec = read_recording(run_dir)
    # the regular axis from the median offset: within the printed resolution of the truth
    np.testing.assert_allclose(rec.time_s, exact, rtol=0, atol=0.5 * 10.0**-decimals)
    assert np.all(np.diff(rec.time_s) > 0)
    assert "too few digits" in caplog.text


def test_rounded_time_column_with_a_jump_is_still_an_error(make_run):
    """Rounding explains ties, not a jump: a rounded axis with 10 ms missing is refused."""
    n = int(FS * DURATION_S)
    exact = np.arange(n) / FS
    exact[n // 2 :] += 0.01
    run_dir = make_run("csv", time_s=np.round(exact, 3))
    with pytest.raises(BouncelabError, match="time_s is not strictly increasing"):
        read_recording(run_dir)


@pytest.mark.parametrize("compressed", [False, True])
def test_npz_stored_and_compressed_and_integer(make_run, compressed):
    """Both NPZ storage paths (memory-mapped stored member, zlib member) give the values;
    integer arrays are converted to float64 volts unchanged."""
    sig = known_signals()
    sig["continuity"] = (sig["continuity"] * 1000).astype(np.int32)
    rec = read_recording(make_run("npz", signals=sig, compressed=compressed))
    np.testing.assert_array_equal(rec.channels["continuity"], sig["continuity"].astype(float))
    np.testing.assert_array_equal(rec.channels["accel"], sig["accel"])


def test_roles_subset_and_unmapped_roles(make_run):
    sig = known_signals()
    del sig["accel"]
    run_dir = make_run("csv", signals=sig, yaml_overrides={"channels": {"continuity": "cont_v"}})
    rec = read_recording(load_run(run_dir), roles=("continuity", "accel"))
    assert list(rec.channels) == ["continuity"]  # accel unmapped: skipped, not an error
    with pytest.raises(ValueError, match="unknown channel role"):
        read_recording(load_run(run_dir), roles=("cont",))


def test_two_roles_on_one_column_do_not_alias(make_run):
    run_dir = make_run(
        "csv", yaml_overrides={"channels": {"continuity": "cont_v", "drive": "cont_v"}}
    )
    rec = read_recording(run_dir)
    rec.channels["drive"][0] += 1.0
    assert rec.channels["continuity"][0] != rec.channels["drive"][0]


def test_step_table_ends_steps_at_next_start_and_recording_end(make_run):
    run = load_run(make_run("csv"))
    rec = read_recording(run)
    table = step_table(run, rec.duration_s)
    assert list(table.columns[:4]) == ["step", "gamma", "t_start_s", "t_end_s"]
    np.testing.assert_array_equal(table["t_start_s"], [t for t, _ in STEPS])
    # reference: each step ends where the next starts, the last at the recording's end
    np.testing.assert_array_equal(table["t_end_s"], [1.0, 2.0, 3.0, DURATION_S])
    np.testing.assert_array_equal(table["gamma"], [g for _, g in STEPS])
    np.testing.assert_allclose(table["n_cycles"], 25.0)  # 1 s at 25 Hz


def test_step_table_of_a_drop_run_is_empty(make_run):
    run = load_run(make_run("npz", kind="drop"))
    table = step_table(run, DURATION_S)
    assert len(table) == 0
    assert list(table.columns[:4]) == ["step", "gamma", "t_start_s", "t_end_s"]


def test_audio_read_holds_one_copy(tmp_path, make_run):
    """Peak traced memory while reading 3 channels of audio stays near the output itself.

    Reference: the output is 3 float32 arrays (12 bytes per frame); the block buffer adds
    64 Ki frames x 3 x 4 B = 0.8 MB. Allow the output plus 4 MB: a second full copy of
    the recording (as sf.read + slicing would make) would exceed it by far.
    """
    n = 600_000
    t = np.arange(n) / FS
    sig = {
        "continuity": (np.sin(2 * np.pi * 3 * t) > 0).astype(float) * 0.8,
        "drive": 0.5 * np.sin(2 * np.pi * 25 * t),
        "accel": 0.2 * np.sin(2 * np.pi * 50 * t),
    }
    run = load_run(make_run("flac", signals=sig))
    tracemalloc.start()
    try:
        rec = read_recording(run)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    out_bytes = sum(a.nbytes for a in rec.channels.values())
    assert out_bytes == n * 12
    assert peak < out_bytes + 4_000_000, f"peak {peak / 1e6:.1f} MB for {out_bytes / 1e6} MB"


@pytest.mark.parametrize("sep", [";", "\t"])
def test_csv_with_semicolon_or_tab_separator(make_run, sep):
    """Reference: the written signal, exactly (float repr round-trips)."""
    sig = known_signals()
    run_dir = make_run("csv", signals=sig)
    p = run_dir / "rec.csv"
    p.write_text(p.read_text().replace(",", sep))
    rec = read_recording(run_dir)
    np.testing.assert_array_equal(rec.channels["drive"], sig["drive"])


def _as_export(text: str, comments: bool, units: bool, european: bool) -> str:
    """A CSV text as data-acquisition software writes it: ``#`` comment lines first, a
    units row under the header, ``;`` separators with decimal commas."""
    header, *rows = text.splitlines()
    if european:
        header = header.replace(",", ";")
        rows = [r.replace(",", ";").replace(".", ",") for r in rows]
    sep = ";" if european else ","
    lines = [header] + ([sep.join(["V"] * len(header.split(sep)))] if units else []) + rows
    if comments:
        lines = ["# exported by a DAQ program", "# sample rate: see run.yaml"] + lines
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "comments,units,european",
    [(True, False, False), (False, True, False), (False, False, True), (True, True, True)],
)
def test_csv_exports_with_comments_units_row_or_decimal_commas(make_run, comments, units, european):
    """Reference: the written signal, exactly; the same file without those features reads
    the same, and a units row is not taken for samples."""
    sig = known_signals()
    run_dir = make_run("csv", signals=sig)
    p = run_dir / "rec.csv"
    p.write_text(_as_export(p.read_text(), comments, units, european))
    rec = read_recording(run_dir)
    for role, values in sig.items():
        np.testing.assert_array_equal(rec.channels[role], values)
    assert rec.n_samples == len(next(iter(sig.values())))


def test_csv_text_in_the_samples_is_still_one_error(make_run):
    """A text cell among the samples (not a units row right under the header) stays an
    error that names the file."""
    run_dir = make_run("csv", signals=known_signals())
    p = run_dir / "rec.csv"
    lines = p.read_text().splitlines()
    lines[5] = ",".join(["oops"] * len(lines[5].split(",")))
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(BouncelabError, match="rec.csv: cannot read CSV samples"):
        read_recording(run_dir)


@settings(max_examples=50, deadline=None)
@given(
    starts=st.lists(st.floats(0, 1000, allow_nan=False), min_size=1, max_size=30, unique=True).map(
        sorted
    ),
    tail=st.floats(1e-3, 100),
)
def test_step_table_tiles_the_recording(starts, tail):
    """Property: steps cover [first start, end) without gaps or overlaps, in order."""
    run = Run(
        run_id="p",
        path=Path("p"),
        kind="sweep",
        recording_path=Path("p/rec.csv"),
        sample_rate_hz=1000.0,
        channels={"continuity": "c"},
        drive_frequency_hz=10.0,
        gamma_steps=[(t, 1.0 + i) for i, t in enumerate(starts)],
    )
    end = starts[-1] + tail
    table = step_table(run, end)
    assert (table["t_end_s"] > table["t_start_s"]).all()
    np.testing.assert_array_equal(table["t_end_s"].to_numpy()[:-1], table["t_start_s"][1:])
    assert table["t_end_s"].iloc[-1] == end
    np.testing.assert_allclose(table["n_cycles"].sum(), (end - starts[0]) * 10.0, rtol=1e-9)
