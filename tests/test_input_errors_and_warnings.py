"""The one-line error and the collection of warnings (:mod:`bouncelab.errors`)."""

from __future__ import annotations

import logging
import pickle

from bouncelab.errors import BouncelabError, collected_warnings


def test_warnings_logged_inside_the_block_are_kept_and_still_reach_other_handlers(caplog):
    log = logging.getLogger("bouncelab.flights.extract")
    with caplog.at_level("WARNING"), collected_warnings() as kept:
        log.warning("%s: a dirty contact (%d openings)", "rec.wav", 3)
        log.info("not a warning")
        logging.getLogger("elsewhere").warning("not ours")
    log.warning("after the block")
    assert kept == ["rec.wav: a dirty contact (3 openings)"]
    assert "a dirty contact" in caplog.text and "after the block" in caplog.text


def test_without_any_handler_the_warning_is_still_printed(capsys):
    # logging prints a record no handler takes to stderr; the collecting handler must
    # not take that away (the command line's warnings)
    root = logging.getLogger()
    saved = root.handlers[:]
    root.handlers.clear()
    try:
        with collected_warnings() as kept:
            logging.getLogger("bouncelab.runs.readers").warning("x.csv: time_s rounded")
    finally:
        root.handlers[:] = saved
    assert kept == ["x.csv: time_s rounded"]
    assert "x.csv: time_s rounded" in capsys.readouterr().err
    # nested blocks (the diagnosis command around the extraction): both keep it, it is
    # printed once
    root.handlers.clear()
    try:
        with collected_warnings() as outer, collected_warnings() as inner:
            logging.getLogger("bouncelab.flights.extract").warning("rec.wav: dirty")
    finally:
        root.handlers[:] = saved
    assert outer == inner == ["rec.wav: dirty"]
    assert capsys.readouterr().err.count("rec.wav: dirty") == 1


def test_an_error_is_one_line_naming_the_file_and_survives_a_worker_process():
    err = BouncelabError("raw/r1/run.yaml", "missing key\n  'gamma_steps'")
    assert str(err) == "raw/r1/run.yaml: missing key 'gamma_steps'"
    again = pickle.loads(pickle.dumps(err))
    assert isinstance(again, BouncelabError) and str(again) == str(err)
