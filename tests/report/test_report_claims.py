"""The seed's claims table (report.claims): what it reads from the results folder."""

from __future__ import annotations

import json

from bouncelab.report.claims import claims_table


def _calibration(results, run, mu, e):
    folder = results / "runs" / run
    folder.mkdir(parents=True)
    cal = {"mu": mu, "mu_ci": [mu - 0.002, mu + 0.002], "restitution": e,
           "restitution_ci": [e - 0.002, e + 0.002], "n_bounces": 5}  # fmt: skip
    (folder / "calibration.json").write_text(json.dumps(cal))


def test_every_drop_run_has_its_rows_against_the_seeds_values(tmp_path):
    """Two drop tests (the seed's body and a lighter one): each gets its friction and
    restitution rows, named by its run, with its own verdict against the seed's 0.29 g and
    0.515 (within the interval widened by 0.02). Before, the first by name stood alone for
    both. A drop run whose calibration failed has no rows."""
    results = tmp_path / "results"
    _calibration(results, "a_light_body", 0.10, 0.70)
    _calibration(results, "drop_test", 0.29, 0.515)
    table = claims_table(results, [], ["a_light_body", "drop_test", "broken_drop"], {})
    rows = [r for r in table["rows"] if "(drop test)" in r[0]]
    assert [(r[0].split()[0], r[2].split()[-1], r[3]) for r in rows] == [
        ("friction", "(a_light_body)", "differs"),
        ("coefficient", "(a_light_body)", "differs"),
        ("friction", "(drop_test)", "agrees"),
        ("coefficient", "(drop_test)", "agrees"),
    ]


def test_without_a_drop_run_the_table_says_so(tmp_path):
    table = claims_table(tmp_path, [], [], {})
    assert table["rows"][0][2] == "no drop run"
