"""run.yaml parsing: attributes, defaults, unknown keys, schema, discovery, Gamma gaps."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest
from runs_fixtures import DRIVE_HZ, FS, STEPS, base_yaml, write_yaml

from bouncelab.errors import BouncelabError
from bouncelab.runs import discover_runs, gamma_gaps, load_run, run_schema


def test_load_run_attributes_and_defaults(make_run):
    run_dir = make_run("flac", name="sweep-01.a", yaml_overrides={"lab_notes": {"x": 1}})
    run = load_run(run_dir)
    assert run.run_id == "sweep-01.a"
    assert run.path == run_dir
    assert run.kind == "sweep"
    assert run.recording_path == run_dir / "rec.flac"
    assert run.format == "flac" and run.is_audio
    assert run.sample_rate_hz == FS
    assert run.channels == {"continuity": 0, "drive": 1, "accel": 2}
    assert run.drive_frequency_hz == DRIVE_HZ
    assert run.gamma_steps == STEPS
    # defaults of CONTRACTS.md section 1
    assert run.full_scale_v == 1.0
    assert run.contact_level == "auto"
    assert run.settle_cycles == 10
    assert run.mass_kg == 0.249 and run.source == "synthetic"
    assert run.drop_height_m is None and run.release_t_s is None
    assert run.extra == {"lab_notes": {"x": 1}}  # unknown keys kept


def test_drop_run(make_run):
    run = load_run(make_run("wav", kind="drop", yaml_overrides={"contact_level": "low"}))
    assert run.kind == "drop"
    assert run.drop_height_m == 0.05 and run.release_t_s == 0.5
    assert run.gamma_steps == [] and run.drive_frequency_hz is None
    assert run.contact_level == "low"


def test_run_id_from_dot_and_trailing_slash(make_run, monkeypatch):
    run_dir = make_run("csv", name="r1")
    assert load_run(str(run_dir) + "/").run_id == "r1"
    monkeypatch.chdir(run_dir)
    assert load_run(".").run_id == "r1"


def test_yaml_scientific_notation_and_unknown_roles(make_run):
    """``2e3`` is a float (YAML 1.2), not the string PyYAML 1.1 would make of it."""
    run_dir = make_run("npz")
    text = (
        (run_dir / "run.yaml").read_text().replace("sample_rate_hz: 2000.0", "sample_rate_hz: 2e3")
    )
    text = text.replace("accel: accel_v", "accel: accel_v\n  temperature: temp_v")
    (run_dir / "run.yaml").write_text(text)
    run = load_run(run_dir)
    assert run.sample_rate_hz == 2000.0
    assert run.extra_channels == {"temperature": "temp_v"}
    assert "temperature" not in run.channels


def test_schema_is_valid_and_accepts_the_fixture_yaml():
    schema = run_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    for fmt in ("flac", "csv", "tdms"):
        for kind in ("sweep", "drop"):
            jsonschema.validate(base_yaml(fmt, kind), schema)
    # the packaged file is the one loaded
    pkg = Path(__file__).parents[2] / "src" / "bouncelab" / "schemas" / "run.schema.json"
    assert json.loads(pkg.read_text()) == schema


@pytest.mark.parametrize(
    ("override", "word"),
    [
        ({"settle_cycles": -1}, "settle_cycles"),
        ({"settle_cycles": 2.5}, "settle_cycles"),
        ({"mass_kg": 0}, "mass_kg"),
        ({"source": "lab-ish"}, "source"),
        ({"gamma_steps": []}, "gamma_steps"),
        ({"gamma_steps": [{"t_s": 0}]}, "gamma"),
        ({"gamma_steps": [{"t_s": 0, "gamma": -1}]}, "gamma_steps[0].gamma"),
        ({"channels": {"continuity": -1}}, "channels.continuity"),
        ({"channels": {"continuity": True}}, "channels.continuity"),
        ({"recording": ""}, "recording"),
        ({"accel_v_per_g": 0}, "accel_v_per_g"),
    ],
)
def test_schema_errors_name_the_key(make_run, override, word):
    run_dir = make_run("flac", yaml_overrides=override)
    with pytest.raises(BouncelabError) as info:
        load_run(run_dir)
    assert info.value.path == run_dir / "run.yaml"
    assert word in info.value.problem
    assert "\n" not in str(info.value)


def test_same_start_time_is_not_sorted(make_run):
    steps = [{"t_s": 0, "gamma": 1}, {"t_s": 0, "gamma": 2}]
    with pytest.raises(BouncelabError, match="sorted"):
        load_run(make_run("csv", yaml_overrides={"gamma_steps": steps}))


def test_recording_in_a_subfolder_is_allowed(make_run):
    run_dir = make_run("csv")
    (run_dir / "data").mkdir()
    (run_dir / "rec.csv").rename(run_dir / "data" / "rec.csv")
    doc = base_yaml("csv") | {"recording": "data/../data/rec.csv"}
    write_yaml(run_dir / "run.yaml", doc)
    assert load_run(run_dir).recording_path == run_dir / "data" / "rec.csv"


def test_upper_case_extension(make_run):
    run_dir = make_run("wav")
    (run_dir / "rec.wav").rename(run_dir / "REC.WAV")
    write_yaml(run_dir / "run.yaml", base_yaml("wav") | {"recording": "REC.WAV"})
    assert load_run(run_dir).format == "wav"


def test_discover_runs(tmp_path, make_run):
    make_run("csv", name="b_run")
    make_run("npz", name="a_run")
    (tmp_path / "raw" / "notes").mkdir()  # no run.yaml: not a run
    (tmp_path / "raw" / ".hidden").mkdir()
    (tmp_path / "raw" / ".hidden" / "run.yaml").write_text("kind: sweep\n")
    (tmp_path / "raw" / "README.md").write_text("x")
    found = discover_runs(tmp_path / "raw")
    assert [p.name for p in found] == ["a_run", "b_run"]
    with pytest.raises(BouncelabError, match="not found"):
        discover_runs(tmp_path / "nothing")


def test_gamma_gaps_reconstruct_the_seed_gaps():
    """Seed paper: data gaps at Gamma 1.75-1.95 and 4.55-4.85 in a sweep 0 to 8.

    Reference grid: 0.05 steps with the Gammas strictly inside those ranges left out;
    the gaps found must be exactly the two ranges (to 1e-9, the rounding used)."""
    grid = [round(0.05 * i, 2) for i in range(161)]
    gammas = [g for g in grid if not (1.75 < g < 1.95 or 4.55 < g < 4.85)]
    gaps = gamma_gaps(gammas)
    assert gaps == [pytest.approx((1.75, 1.95)), pytest.approx((4.55, 4.85))]


def test_gamma_gaps_regular_and_up_down_sweeps_have_none():
    up = [0.1 * i for i in range(41)]
    assert gamma_gaps(up) == []
    assert gamma_gaps(up + up[::-1]) == []  # a sweep up and back covers the same values
    assert gamma_gaps([1.0, 2.0]) == []  # too few steps to have a typical spacing
