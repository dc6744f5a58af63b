"""``bouncelab simulate`` (CONTRACTS.md sections 2 and 5)."""

import subprocess
import sys

import pandas as pd

from bouncelab.cli import main
from bouncelab.physics import FLIGHT_COLUMNS


def test_simulate_writes_contract_columns(tmp_path):
    out = tmp_path / "sim.parquet"
    rc = main(
        [
            "simulate", "--model", "friction+restitution", "--set", "mu=0.29", "--set",
            "e=0.515", "--gamma", "1.5:4:6", "--flights", "20", "--skip", "10", "-o", str(out),
        ]
    )  # fmt: skip
    assert rc == 0
    df = pd.read_parquet(out)
    for col in ("gamma", "T", "phi_takeoff", "phi_landing"):
        assert col in df.columns
    assert set(FLIGHT_COLUMNS) <= set(df.columns)
    assert sorted(df["gamma"].unique()) == [1.5, 2.0, 2.5, 3.0, 3.5, 4.0]
    assert (df.groupby("gamma").size() == 20).all()
    assert df["phi_takeoff"].between(0, 6.2832).all()


def test_simulate_csv(tmp_path):
    out = tmp_path / "sim.csv"
    assert main(["simulate", "--model", "ideal", "--gamma", "2:3:2", "-o", str(out)]) == 0
    df = pd.read_csv(out)
    assert len(df) == 2 * 200


def test_bad_set_gives_one_error_line(tmp_path):
    out = tmp_path / "x.parquet"
    r = subprocess.run(
        [sys.executable, "-m", "bouncelab", "simulate", "--model", "friction", "--set",
         "e=0.5", "--gamma", "1:2:3", "-o", str(out)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "'e'" in lines[0]
    assert not out.exists()


def test_bad_grid_and_model_and_output(tmp_path, capsys):
    for argv in (
        ["--model", "ideal", "--gamma", "3:1:5"],
        ["--model", "ideal", "--gamma", "1:2"],
        ["--model", "bogus", "--gamma", "1:2:3"],
        ["--model", "ideal", "--set", "mu", "--gamma", "1:2:3"],
    ):
        assert main(["simulate", *argv, "-o", str(tmp_path / "a.parquet")]) == 2
    assert (
        main(["simulate", "--model", "ideal", "--gamma", "1:2:3", "-o", str(tmp_path / "a.txt")])
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 5 and all(line.startswith("error:") for line in err)
