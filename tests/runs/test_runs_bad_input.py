"""Bad input through the CLI: one ``error:`` line naming the file and the problem.

Every case of issue 3 section 2 (and a few more): non-zero exit, exactly one stderr
line starting with ``error:``, naming the most relevant file (run.yaml for key
problems, the recording for data problems) and a word of the problem, no traceback,
and the run folder byte-identical afterwards (SHA-256 of every path and byte).
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf
from runs_fixtures import DELETE, FS, known_signals, tree_digest

from bouncelab.cli import main


def _truncate(path, fraction=0.6):
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * fraction)])


def _edit_yaml(run_dir, old, new):
    p = run_dir / "run.yaml"
    text = p.read_text()
    assert old in text, old
    p.write_text(text.replace(old, new))


# each case: builder(make_run, tmp_path) -> run_dir, expected file name, problem word
def case_yaml_missing(mk, tmp):
    d = mk("csv")
    (d / "run.yaml").unlink()
    return d, "run.yaml", "not found"


def case_yaml_syntax(mk, tmp):
    d = mk("csv")
    _edit_yaml(d, "kind: sweep", "kind: [sweep")
    return d, "run.yaml", "YAML syntax error"


def case_yaml_not_mapping(mk, tmp):
    d = mk("csv")
    (d / "run.yaml").write_text("- just\n- a list\n")
    return d, "run.yaml", "mapping"


def case_yaml_duplicate_key(mk, tmp):
    d = mk("csv")
    _edit_yaml(d, "kind: sweep", "kind: sweep\nkind: drop")
    return d, "run.yaml", "duplicate key"


def case_required_key_missing(mk, tmp):
    return mk("csv", yaml_overrides={"sample_rate_hz": DELETE}), "run.yaml", "sample_rate_hz"


def case_sweep_without_steps(mk, tmp):
    return mk("csv", yaml_overrides={"gamma_steps": DELETE}), "run.yaml", "gamma_steps"


def case_sweep_without_frequency(mk, tmp):
    d = mk("csv", yaml_overrides={"drive_frequency_hz": DELETE})
    return d, "run.yaml", "drive_frequency_hz"


def case_drop_without_release(mk, tmp):
    d = mk("csv", kind="drop", yaml_overrides={"release_t_s": DELETE})
    return d, "run.yaml", "release_t_s"


def case_drop_without_height(mk, tmp):
    d = mk("csv", kind="drop", yaml_overrides={"drop_height_m": DELETE})
    return d, "run.yaml", "drop_height_m"


def case_continuity_channel_missing(mk, tmp):
    d = mk("csv", yaml_overrides={"channels": {"drive": "drive_v"}})
    return d, "run.yaml", "continuity"


def case_unknown_kind(mk, tmp):
    return mk("csv", yaml_overrides={"kind": "sweeep"}), "run.yaml", "kind"


def case_format_version(mk, tmp):
    return mk("csv", yaml_overrides={"format_version": 2}), "run.yaml", "format_version"


def case_contact_level(mk, tmp):
    return mk("csv", yaml_overrides={"contact_level": "up"}), "run.yaml", "contact_level"


def case_recording_missing(mk, tmp):
    d = mk("flac")
    (d / "rec.flac").unlink()
    return d, "rec.flac", "not found"


def case_unsupported_extension(mk, tmp):
    d = mk("csv")
    (d / "rec.csv").rename(d / "rec.mp3")
    _edit_yaml(d, "rec.csv", "rec.mp3")
    return d, "run.yaml", "unsupported extension"


def case_truncated_wav(mk, tmp):
    d = mk("wav")
    _truncate(d / "rec.wav")
    return d, "rec.wav", "truncated"


def case_truncated_flac(mk, tmp):
    d = mk("flac")
    _truncate(d / "rec.flac")
    return d, "rec.flac", "truncated"


def case_corrupt_flac(mk, tmp):
    d = mk("flac")
    (d / "rec.flac").write_bytes(np.random.default_rng(1).bytes(4000))
    return d, "rec.flac", "corrupt"


def case_corrupt_flac_body(mk, tmp):
    d = mk("flac")
    p = d / "rec.flac"
    data = bytearray(p.read_bytes())
    data[len(data) // 2 : len(data) // 2 + 600] = np.random.default_rng(2).bytes(600)
    p.write_bytes(bytes(data))
    return d, "rec.flac", "corrupt"


def case_flac_of_unknown_length(mk, tmp):
    """STREAMINFO total_samples = 0 (streaming encoders): libsndfile cannot find the end."""
    d = mk("flac")
    p = d / "rec.flac"
    data = bytearray(p.read_bytes())
    data[21] &= 0xF0  # total_samples: 36 bits from bit 108 of STREAMINFO (byte 8 on)
    data[22:26] = b"\0\0\0\0"
    p.write_bytes(bytes(data))
    return d, "rec.flac", "no length"


def case_corrupt_npz(mk, tmp):
    d = mk("npz")
    _truncate(d / "rec.npz", 0.5)
    return d, "rec.npz", "NPZ"


def case_corrupt_tdms(mk, tmp):
    d = mk("tdms")
    (d / "rec.tdms").write_bytes(b"TDSm" + np.random.default_rng(3).bytes(200))
    return d, "rec.tdms", "TDMS"


def case_truncated_tdms(mk, tmp):
    d = mk("tdms")
    _truncate(d / "rec.tdms", 0.7)
    return d, "rec.tdms", "TDMS"


def case_sample_rate_mismatch(mk, tmp):
    d = mk("wav", yaml_overrides={"sample_rate_hz": 44100})
    return d, "run.yaml", "sample_rate_hz"


def case_channel_index_out_of_range(mk, tmp):
    d = mk("flac", yaml_overrides={"channels": {"continuity": 0, "drive": 3}})
    return d, "run.yaml", "out of range"


def case_audio_channel_by_name(mk, tmp):
    d = mk("flac", yaml_overrides={"channels": {"continuity": "left"}})
    return d, "run.yaml", "channel index"


def case_csv_column_missing(mk, tmp):
    d = mk("csv", yaml_overrides={"channels": {"continuity": "contact"}})
    return d, "run.yaml", "column 'contact'"


def case_npz_array_missing(mk, tmp):
    d = mk("npz", yaml_overrides={"channels": {"continuity": "contact"}})
    return d, "run.yaml", "array 'contact'"


def case_tdms_channel_missing(mk, tmp):
    d = mk("tdms", yaml_overrides={"channels": {"continuity": "rig/contact"}})
    return d, "run.yaml", "rig/contact"


def case_nan_sample_csv(mk, tmp):
    sig = known_signals()
    sig["continuity"][1234] = np.nan
    return mk("csv", signals=sig), "rec.csv", "non-finite"


def case_empty_cell_csv(mk, tmp):
    d = mk("csv")
    p = d / "rec.csv"
    lines = p.read_text().splitlines()
    lines[10] = "," + lines[10].split(",", 1)[1]  # first column (continuity) left empty
    p.write_text("\n".join(lines) + "\n")
    return d, "rec.csv", "non-finite"


def case_inf_sample_npz(mk, tmp):
    sig = known_signals()
    sig["drive"][7] = np.inf
    return mk("npz", signals=sig), "rec.npz", "non-finite"


def case_nan_sample_float_wav(mk, tmp):
    sig = known_signals()
    sig["accel"][99] = np.nan
    return mk("wav", signals=sig, subtype="FLOAT"), "rec.wav", "non-finite"


def case_nan_sample_tdms(mk, tmp):
    sig = known_signals()
    sig["continuity"][0] = np.nan
    return mk("tdms", signals=sig), "rec.tdms", "non-finite"


def case_non_numeric_csv(mk, tmp):
    d = mk("csv")
    p = d / "rec.csv"
    lines = p.read_text().splitlines()
    lines[5] = "open," + lines[5].split(",", 1)[1]
    p.write_text("\n".join(lines) + "\n")
    return d, "rec.csv", "cannot read CSV"


def case_time_not_increasing(mk, tmp):
    t = np.arange(int(FS * 4)) / FS
    t[500] = t[498]
    return mk("csv", time_s=t), "rec.csv", "time_s is not strictly increasing"


def case_time_spacing_twice_the_sample_period(mk, tmp):
    # read, every sample was a data gap: an empty flight table, exit 0
    t = np.arange(int(FS * 4)) * (2.0 / FS)
    return mk("csv", time_s=t), "rec.csv", "disagree about the sampling rate"


def case_steps_unsorted(mk, tmp):
    steps = [{"t_s": 0.0, "gamma": 1.0}, {"t_s": 2.0, "gamma": 1.5}, {"t_s": 1.0, "gamma": 2}]
    return mk("csv", yaml_overrides={"gamma_steps": steps}), "run.yaml", "sorted"


def case_steps_after_end(mk, tmp):
    steps = [{"t_s": 5.0, "gamma": 1.0}]  # the recording lasts 4 s
    return mk("npz", yaml_overrides={"gamma_steps": steps}), "run.yaml", "after the end"


def case_release_after_end(mk, tmp):
    d = mk("csv", kind="drop", yaml_overrides={"release_t_s": 9.0})
    return d, "run.yaml", "release_t_s"


def case_drive_frequency_zero(mk, tmp):
    d = mk("csv", yaml_overrides={"drive_frequency_hz": 0})
    return d, "run.yaml", "drive_frequency_hz"


def case_drive_frequency_negative(mk, tmp):
    d = mk("csv", yaml_overrides={"drive_frequency_hz": -30.0})
    return d, "run.yaml", "drive_frequency_hz"


def case_sample_rate_infinite(mk, tmp):
    d = mk("csv")
    _edit_yaml(d, "sample_rate_hz: 2000.0", "sample_rate_hz: .inf")
    return d, "run.yaml", "finite"


def case_empty_csv(mk, tmp):
    d = mk("csv")
    p = d / "rec.csv"
    p.write_text(p.read_text().splitlines()[0] + "\n")  # header only
    return d, "rec.csv", "empty"


def case_empty_csv_file(mk, tmp):
    d = mk("csv")
    (d / "rec.csv").write_text("")
    return d, "rec.csv", "empty"


def case_empty_wav(mk, tmp):
    d = mk("wav")
    sf.write(d / "rec.wav", np.zeros((0, 3)), int(FS), subtype="PCM_16")
    return d, "rec.wav", "empty"


def case_empty_npz(mk, tmp):
    empty = {r: np.zeros(0) for r in ("continuity", "drive", "accel")}
    return mk("npz", signals=empty), "rec.npz", "empty"


def case_npz_lengths_differ(mk, tmp):
    sig = known_signals()
    sig["drive"] = sig["drive"][:-1]
    return mk("npz", signals=sig), "rec.npz", "length"


def case_path_leaves_folder(mk, tmp):
    d = mk("csv")
    outside = d.parent / "elsewhere.csv"
    (d / "rec.csv").rename(outside)
    _edit_yaml(d, "recording: rec.csv", "recording: ../elsewhere.csv")
    return d, "run.yaml", "inside the run folder"


def case_absolute_path(mk, tmp):
    d = mk("csv")
    _edit_yaml(d, "recording: rec.csv", f"recording: {(d / 'rec.csv').resolve()}")
    return d, "run.yaml", "inside the run folder"


def case_folder_name_space(mk, tmp):
    return mk("csv", name="bad name"), "bad name", "does not match"


def case_folder_name_leading_dot(mk, tmp):
    return mk("csv", name="_underscore_first"), "_underscore_first", "does not match"


def case_folder_is_a_file(mk, tmp):
    d = mk("csv")
    return d / "run.yaml", "run.yaml", "not a folder"


def case_folder_missing(mk, tmp):
    return tmp / "raw" / "nope", "nope", "not found"


def case_drive_phase_offset_text(mk, tmp):
    """A documented extension key with a unit written in: extract failed with an internal
    error that named no file (a black-box probe's case)."""
    return mk("csv", yaml_overrides={"drive_phase_offset_rad": "0.6 rad"}), "run.yaml", "number"


def case_drive_phase_offset_nan(mk, tmp):
    """.nan: every phase came out NaN without a word."""
    return mk("csv", yaml_overrides={"drive_phase_offset_rad": float("nan")}), "run.yaml", "finite"


def case_gravity_not_positive(mk, tmp):
    return mk("csv", kind="drop", yaml_overrides={"g_m_s2": 0.0}), "run.yaml", "positive"


CASES = {name[5:]: fn for name, fn in dict(globals()).items() if name.startswith("case_")}


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_input_gives_one_error_line(make_run, tmp_path, capsys, name):
    run_dir, expected_file, word = CASES[name](make_run, tmp_path)
    before = tree_digest(run_dir) if run_dir.exists() else None
    parent_before = tree_digest(run_dir.parent) if run_dir.parent.exists() else None
    code = main(["validate", str(run_dir)])
    out, err = capsys.readouterr()
    assert code != 0
    lines = err.splitlines()
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("error: "), line
    assert "internal error" not in line, line  # a BouncelabError, not a crash
    assert "Traceback" not in err
    file_named = line[len("error: ") :].split(": ", 1)[0]
    assert os.path.basename(file_named.rstrip("/")) == expected_file, line
    assert word.lower() in line.lower(), line
    if before is not None:
        assert tree_digest(run_dir) == before
    if parent_before is not None:
        assert tree_digest(run_dir.parent) == parent_before
    assert "ok" not in out.split()


def test_every_issue_case_is_covered():
    """Issue 3 section 2, one case per item (names of the builders above)."""
    required = {
        "yaml_missing", "yaml_syntax", "required_key_missing", "unknown_kind",
        "recording_missing", "unsupported_extension", "truncated_wav", "corrupt_flac",
        "sample_rate_mismatch", "channel_index_out_of_range", "csv_column_missing",
        "nan_sample_csv", "inf_sample_npz", "time_not_increasing", "steps_unsorted",
        "steps_after_end", "drive_frequency_zero", "drive_frequency_negative", "empty_csv",
        "path_leaves_folder", "folder_name_space",
    }  # fmt: skip
    assert required <= set(CASES)


@pytest.mark.parametrize(
    "name",
    ["nan_sample_csv", "corrupt_flac", "corrupt_flac_body", "truncated_flac", "corrupt_tdms"],
)
def test_error_through_a_real_process(make_run, tmp_path, name):
    """A real process: exit 2, one stderr line, no traceback, nothing printed by C
    libraries (libsndfile's decoders) or by npTDMS's logging."""
    run_dir, expected_file, _ = CASES[name](make_run, tmp_path)
    before = tree_digest(run_dir)
    proc = subprocess.run(
        [sys.executable, "-m", "bouncelab", "validate", str(run_dir)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("error: ")
    assert expected_file in proc.stderr and "Traceback" not in proc.stderr
    assert tree_digest(run_dir) == before


@pytest.mark.parametrize("path", ["raw/run_a/run.yaml", None])
def test_an_error_survives_pickling_as_itself(path):
    """A worker process (the diagnosis's evaluation pool) sends its errors pickled: the
    caller must get the same file and problem back, not a broken pool."""
    import pickle
    from pathlib import Path

    from bouncelab.errors import BouncelabError

    err = pickle.loads(pickle.dumps(BouncelabError(path, "no  contacts\nfound")))
    assert isinstance(err, BouncelabError)
    assert str(err) == (f"{path}: no contacts found" if path else "no contacts found")
    assert err.path == (None if path is None else Path(path))
    assert err.problem == "no contacts found"
