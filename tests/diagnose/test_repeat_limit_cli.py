"""``bouncelab diagnose --repeat-limit RAD`` (and the workflow's
``diagnosis: repeat_limit_rad``): the limit of the repeat rule reaches the diagnosis, and
a limit that is not positive is one error line."""

from __future__ import annotations

import pytest

from bouncelab.cli import main


@pytest.fixture
def settings_seen(monkeypatch):
    """``diagnose_flights`` replaced by one that records its ``select_settings``."""
    from test_retry import _result

    import bouncelab.gap.diagnose as diag

    seen = []

    def fake(run, table, duration, *, seed, select_settings=None, **kw):
        seen.append(select_settings)
        return _result(seed, ["friction"], False, 1.0, 10)

    monkeypatch.setattr(diag, "diagnose_flights", fake)
    return seen


def test_the_limit_reaches_the_diagnosis(null_run, settings_seen, tmp_path):
    from bouncelab.gap.select import SelectSettings

    run_dir, flights = null_run
    args = ["diagnose", str(run_dir), "--flights", str(flights), "-o", str(tmp_path / "d.json")]
    assert main(args) == 0
    assert main([*args, "--repeat-limit", "0.05"]) == 0
    default, raised = settings_seen
    assert default is None  # the diagnosis's own SelectSettings(): repeat_limit 0.02
    assert SelectSettings().repeat_limit == 0.02
    assert raised.repeat_limit == 0.05
    assert raised.unexplained_ratio == SelectSettings().unexplained_ratio


@pytest.mark.parametrize("value", ["0", "-0.1"])
def test_a_limit_not_above_zero_is_one_error_line(null_run, tmp_path, capsys, value):
    run_dir, flights = null_run
    args = ["diagnose", str(run_dir), "--flights", str(flights), "-o", str(tmp_path / "d.json")]
    assert main([*args, "--repeat-limit", value]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--repeat-limit must be > 0" in err[0]
