"""``bouncelab validate`` on good runs of every format: exit 0 and what it reports."""

from __future__ import annotations

import json

import numpy as np
import pytest
from runs_fixtures import DRIVE_HZ, DURATION_S, FORMATS, FS, STEPS, known_signals, tree_digest

from bouncelab.cli import main
from bouncelab.errors import BouncelabError
from bouncelab.runs import load_run, read_recording, step_table, validate_run


@pytest.mark.parametrize("fmt", FORMATS)
def test_validate_good_run_every_format(make_run, capsys, fmt):
    run_dir = make_run(fmt)
    before = tree_digest(run_dir)
    assert main(["validate", str(run_dir)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert f"run_{fmt}" in out and "sweep" in out
    assert f"{FS:g} Hz" in out and f"{int(FS * DURATION_S)} samples" in out
    for role in ("continuity", "drive", "accel"):
        assert role in out
    assert "steps      4, Gamma 0.5 .. 2.5" in out
    assert out.rstrip().endswith("ok")
    assert tree_digest(run_dir) == before


def test_validate_json_reports_ranges_and_steps(make_run, capsys):
    sig = known_signals()
    run_dir = make_run("npz", signals=sig)
    assert main(["validate", str(run_dir), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["run"] == "run_npz" and doc["format"] == "npz"
    assert doc["n_steps"] == len(STEPS)
    assert doc["gamma_min"] == 0.5 and doc["gamma_max"] == 2.5
    assert doc["duration_s"] == pytest.approx(DURATION_S)
    ranges = {c["role"]: (c["min_v"], c["max_v"]) for c in doc["channels"]}
    # reference: the written signal's own extremes (NPZ is exact)
    for role, v in sig.items():
        assert ranges[role] == (float(np.min(v)), float(np.max(v)))


def test_validate_reports_gamma_gaps(make_run, capsys):
    gammas = [0.5, 0.6, 0.7, 0.8, 1.1, 1.2, 1.3]  # 0.8 -> 1.1 is 3 times the spacing
    steps = [{"t_s": 0.5 * i, "gamma": g} for i, g in enumerate(gammas)]
    run_dir = make_run("csv", yaml_overrides={"gamma_steps": steps})
    assert main(["validate", str(run_dir)]) == 0
    out = capsys.readouterr().out
    assert "gaps       Gamma 0.8 .. 1.1" in out
    assert "settle_cycles" not in out  # 0.5 s at 25 Hz = 12.5 cycles: longer than 10


def test_steps_too_short_to_settle_are_a_warning(make_run):
    steps = [{"t_s": 0.3 * i, "gamma": 1 + 0.1 * i} for i in range(4)]  # 0.3 s = 7.5 cycles
    report = validate_run(make_run("csv", yaml_overrides={"gamma_steps": steps}))
    assert any("3 step(s) no longer than settle_cycles" in w for w in report.warnings)


def test_steps_past_the_end_are_left_out_with_a_warning(make_run):
    """A protocol the lab stopped early: the steps that start at or after the end (4 s)
    hold no data and are left out with a warning, the others keep their indices and the
    last one runs to the end. Before, the whole run was refused. Every step past the end
    is still an error (test_runs_bad_input.py, steps_after_end)."""
    steps = [{"t_s": 0.0, "gamma": 1.0}, {"t_s": 4.0, "gamma": 2.0}, {"t_s": 6.0, "gamma": 3}]
    run_dir = make_run("flac", yaml_overrides={"gamma_steps": steps})
    report = validate_run(run_dir)
    (w,) = [w for w in report.warnings if "after the end" in w]
    assert w.startswith("2 gamma step(s)") and "gamma_steps[1] at 4 s" in w
    table = step_table(load_run(run_dir), read_recording(run_dir).duration_s)
    assert table["step"].tolist() == [0] and table["t_end_s"].tolist() == [DURATION_S]


def test_steps_before_a_late_time_axis_are_a_warning(make_run):
    """time_s from a lab clock (100 s at the first sample), steps written from 0: every
    flight would land in the last step starting before 100 s, with its Gamma. Warned;
    steps on the time axis are not (reference: test_runs_readers' lab-clock run)."""
    t = 100.0 + np.arange(int(FS * DURATION_S)) / FS
    report = validate_run(make_run("csv", name="from_zero", time_s=t))
    (w,) = [w for w in report.warnings if "before the recording starts" in w]
    assert w.startswith(f"{len(STEPS) - 1} gamma step(s)")
    steps = [{"t_s": 100.0 + ts, "gamma": g} for ts, g in STEPS]
    on_axis = make_run("csv", name="on_axis", time_s=t, yaml_overrides={"gamma_steps": steps})
    assert not any("before the recording" in w for w in validate_run(on_axis).warnings)


def test_validate_drop_run(make_run, capsys):
    run_dir = make_run("tdms", kind="drop")
    assert main(["validate", str(run_dir)]) == 0
    out = capsys.readouterr().out
    assert "drop       height 0.05 m, released at t = 0.5 s" in out


def test_validate_warns_about_ignored_things(make_run):
    run_dir = make_run("csv", yaml_overrides={"full_scale_v": 2.0, "operator": "ana"})
    report = validate_run(run_dir)
    text = " ".join(report.warnings)
    assert "operator" in text and "full_scale_v" in text
    assert "accel_v_per_g" in text  # accel channel without a sensitivity


def test_time_column_spacing_mismatch_is_a_warning(make_run):
    # spacing says 2.2 kHz, run.yaml says 2 kHz (twice off is an error: bad input cases)
    t = np.arange(int(FS * DURATION_S)) / (1.1 * FS)
    steps = [{"t_s": 0.0, "gamma": 1.0}]
    report = validate_run(make_run("csv", time_s=t, yaml_overrides={"gamma_steps": steps}))
    assert any("time_s spacing" in w for w in report.warnings)


def test_a_drive_frequency_unlike_the_drive_channel_is_a_warning(make_run):
    """run.yaml copied from a run at another frequency: the drive channel is a 25 Hz sine
    (:func:`known_signals`), run.yaml states 24 Hz (-4 %). Reference: the channel's own
    frequency, within 0.01 Hz (1-s steps of 25 cycles: the estimate is within 0.01 %);
    the stated 25 Hz gives no warning."""
    stated_right = validate_run(make_run("npz", name="right"))
    assert not any("drive channel runs at" in w for w in stated_right.warnings)
    wrong = make_run("npz", name="wrong", yaml_overrides={"drive_frequency_hz": 24.0})
    (warning,) = [w for w in validate_run(wrong).warnings if "drive channel runs at" in w]
    measured = float(warning.split("runs at ")[1].split(" Hz")[0])
    assert measured == pytest.approx(DRIVE_HZ, abs=0.01)
    assert "+4.2 % from drive_frequency_hz 24" in warning


def test_a_continuity_channel_with_no_contacts_is_a_warning(make_run):
    """Noise alone on the continuity channel (a disconnected circuit): validate says what
    extract would (no two levels), where before it said only 'ok'; a channel with
    contacts gets no such warning. Found by a black-box probe of the contract."""
    signals = known_signals()
    signals["continuity"] = 2.5 + 0.02 * np.random.default_rng(3).standard_normal(
        signals["continuity"].size
    )
    (warning,) = [
        w
        for w in validate_run(make_run("npz", name="silent", signals=signals)).warnings
        if "no contacts" in w
    ]
    assert warning.startswith("no contacts found: the continuity channel shows no transitions")
    assert "extract and calibrate will fail" in warning
    fine = validate_run(make_run("npz", name="fine"))
    assert not any("no contacts" in w for w in fine.warnings)
    assert fine.extract_problem is None


def test_a_run_with_nothing_to_extract_is_refused_by_the_workflow_check(make_run):
    """The workflow's check refuses a run extract will fail on, naming the recording and
    the problem (before, it passed: under --keep-going the report waited for the run's
    products and was never rebuilt; a black-box probe). A sweep resting below Gamma 1
    with the same silent channel is no fault: no contacts are expected there."""
    from bouncelab.pipeline import check_run_verdict

    signals = known_signals()
    signals["continuity"] = 2.5 + 0.02 * np.random.default_rng(3).standard_normal(
        signals["continuity"].size
    )
    silent = make_run("npz", name="silent", signals=signals)
    verdict = check_run_verdict(silent)
    assert not verdict["ok"]
    # the line extract would print
    assert verdict["error"].startswith(f"{silent / 'rec.npz'}: no contacts found: the continuity")
    assert check_run_verdict(make_run("npz", name="fine"))["ok"]
    steps = [{"t_s": 0.0, "gamma": 0.5}, {"t_s": 1.0, "gamma": 0.8}]
    resting = make_run(
        "npz", name="resting", signals=signals, yaml_overrides={"gamma_steps": steps}
    )
    assert validate_run(resting).extract_problem is None
    assert check_run_verdict(resting)["ok"]


def test_the_documented_extension_keys_are_not_unknown(make_run):
    """drive_phase_offset_rad and g_m_s2 are read (docs/flights.md): validate does not
    call them ignored (a black-box probe read 'unknown keys kept and ignored:
    drive_phase_offset_rad' beside phases that did use it); a key of nobody's still is."""
    run_dir = make_run("csv", yaml_overrides={"drive_phase_offset_rad": 0.3, "operator": "ana"})
    (warning,) = [w for w in validate_run(run_dir).warnings if "unknown keys" in w]
    assert warning.endswith(": operator")


@pytest.mark.parametrize("fmt", ["wav", "flac", "csv"])
def test_a_channel_clipped_at_full_scale_is_a_warning(make_run, fmt):
    """A contact level 30 % beyond a sound card's full scale is read flat there (a black-
    box probe's: flight times 13 us short, median, and nothing said); validate names the
    channel, the side and the share.  A CSV's range is unknown: nothing said; nor for
    the unclipped signals of every format (test above)."""
    sig = known_signals()
    sig["continuity"] = np.where(sig["continuity"] > 0.5, 1.3, 0.05)  # beyond +1 V
    run_dir = make_run(fmt, signals=sig)
    lines = [w for w in validate_run(run_dir).warnings if "clipped" in w]
    if fmt == "csv":
        assert lines == []
    else:
        share = float(np.mean(sig["continuity"] > 1.0))
        assert len(lines) == 1 and lines[0].startswith("continuity channel at +1 V")
        assert f"{100 * share:.2g} % of its samples" in lines[0]


def test_a_jump_of_the_time_axis_is_a_warning(make_run):
    """Samples missing (a DAQ's buffer overrun: time_s jumps 5 ms after 1.5 s, 2 ms
    after 3 s) were passed over in silence by validate and extract (a black-box probe's
    CSV; the flights across a jump are left out). Both now say where and how much."""
    from bouncelab.flights.extract import extract_run

    n = int(FS * DURATION_S)
    time_s = np.arange(n) / FS
    time_s[int(1.5 * FS) :] += 5e-3
    time_s[int(3.0 * FS) :] += 2e-3
    run_dir = make_run("csv", time_s=time_s)
    lines = [w for w in validate_run(run_dir).warnings if "jumps by" in w]
    assert len(lines) == 1 and "at 2 place(s), 7 ms missing in all" in lines[0]
    assert "the largest 5.5 ms after t = 1.4995 s" in lines[0]
    _, qc = extract_run(run_dir)
    assert any("rec.csv: time_s jumps by" in w for w in qc.attrs["warnings"])
    assert not [w for w in validate_run(make_run("csv", name="regular")).warnings if "jumps" in w]


@pytest.mark.parametrize("fmt", ["wav", "npz"])
def test_continuity_and_drive_swapped_are_refused_with_one_line(make_run, fmt):
    """A probe's WAV with the two channels swapped against run.yaml was extracted into
    2045 invented flights and diagnosed, every command exiting 0. The continuity channel
    sits at two levels and a drive does not: validate names it (extract will fail) and
    extract refuses with one line naming run.yaml; the unswapped run is untouched."""
    from bouncelab.flights.extract import extract_run

    sig = known_signals()
    swapped = {**sig, "continuity": sig["drive"], "drive": sig["continuity"]}
    run_dir = make_run(fmt, signals=swapped)
    report = validate_run(run_dir)
    assert report.extract_problem and "swapped in run.yaml" in report.extract_problem
    with pytest.raises(BouncelabError, match="swapped") as err:
        extract_run(run_dir)
    assert "run.yaml" in str(err.value)
    assert validate_run(make_run(fmt, name="right", signals=sig)).extract_problem is None
