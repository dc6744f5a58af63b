"""The report renderer: typst escaping, a self-contained HTML, deterministic output."""

from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from bouncelab.report.render import render_html, render_pdf, typst_escape  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
TEMPLATES = REPO / "report" / "templates"
CSS = REPO / "report" / "style.css"

# text with every character that means something in typst markup or HTML
NASTY = "a_b *c* #d $e$ @f <g> [h] ~i // j /* k */ = l - m + n 'o' \"p\" & q \\ r"


@pytest.fixture
def context(tmp_path):
    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [0, 1])
    png = tmp_path / "figures" / "f.png"
    png.parent.mkdir()
    fig.savefig(png, metadata={"Software": None})
    plt.close(fig)
    blocks = [
        {"type": "text", "text": NASTY},
        {"type": "note", "text": "= " + NASTY},
        {"type": "heading", "id": "h", "text": NASTY},
        {"type": "equation", "text": "T^2/2 = Gamma sin(phi_0)", "note": NASTY},
        {"type": "figure", "id": "f", "title": "F", "path": str(png), "seed": NASTY, "ours": NASTY},
        {"type": "table", "caption": NASTY, "header": ["a", "b"], "rows": [[NASTY, "-1"]]},
        {"type": "code", "text": "key: value\n# comment ``` fence"},
    ]
    return {
        "title": "t",
        "subtitle": NASTY,
        "version": "0",
        "git_revision": "abc",
        "sections": [{"id": "s", "title": NASTY, "blocks": blocks}],
    }


def test_typst_escape_leaves_no_markup():
    out = typst_escape("#a_b*")
    assert out == "\\#a\\_b\\*"


def test_pdf_compiles_with_every_special_character(tmp_path, context):
    pdf = render_pdf(context, TEMPLATES, tmp_path / "report" / "r.pdf", root=tmp_path)
    data = pdf.read_bytes()
    assert data.startswith(b"%PDF")
    assert len(data) > 5000


def test_html_is_self_contained_and_escaped(tmp_path, context):
    html = render_html(context, TEMPLATES, tmp_path / "report" / "r.html", CSS).read_text()
    assert "data:image/png;base64," in html
    assert 'src="http' not in html and "<link" not in html  # opens offline
    assert "<g>" not in html and "&lt;g&gt;" in html  # user text is escaped


def test_rendering_is_deterministic(tmp_path, context):
    a = render_pdf(context, TEMPLATES, tmp_path / "report" / "a.pdf", root=tmp_path).read_bytes()
    b = render_pdf(context, TEMPLATES, tmp_path / "report" / "b.pdf", root=tmp_path).read_bytes()
    assert a == b
    h1 = render_html(context, TEMPLATES, tmp_path / "report" / "a.html", CSS).read_bytes()
    h2 = render_html(context, TEMPLATES, tmp_path / "report" / "b.html", CSS).read_bytes()
    assert h1 == h2


def test_diagnosis_table_shows_e_rigid_plate_beside_the_armature(tmp_path):
    """A step with restitution and the armature shows e in both conventions; one without
    the armature shows none (reference: the JSON values, written as the table prints)."""
    import json

    from bouncelab.report.content import diagnosis_blocks

    run = tmp_path / "runs" / "r"
    run.mkdir(parents=True)
    steps = [
        {"effect": "restitution", "params": {"e": 0.554}, "gap": 0.25, "shrink": 0.3},
        {
            "effect": "feedback",
            "params": {"e": 0.5708, "mass_ratio": 0.0448, "f_ratio": 0.644, "zeta": 0.088},
            "e_rigid_plate": 0.503,
            "gap": 0.05,
            "shrink": 0.5,
        },
    ]
    diag = {"baseline": {"model": "ideal", "gap": 0.37}, "noise_floor": 0.06, "steps": steps}
    (run / "diagnosis.json").write_text(json.dumps(diag))
    blocks = diagnosis_blocks(tmp_path, "r", tmp_path / "captions.yaml")
    (table,) = [b for b in blocks if b.get("header", [""])[0] == "effect"]
    first, second = (row[1] for row in table["rows"])
    assert "e_rigid_plate" not in first
    assert second.endswith("; e_rigid_plate = 0.503") and "e = 0.5708" in second


def test_diagnosis_text_shows_the_verdict_margin_and_the_run_level_warnings(tmp_path):
    """The verdict's margin is printed beside the final gap, and the warnings that belong
    to no step (the selection's and the verdict's) are listed once, while a step's own
    warning stays in its table row only (reference: the JSON values as written)."""
    import json

    from bouncelab.report.content import diagnosis_blocks

    run = tmp_path / "runs" / "r"
    run.mkdir(parents=True)
    step_warning = "e and mass_ratio trade off (bootstrap correlation +0.93)"
    run_warning = "only 2 Gamma steps are held out (2.5, 4): the verdict rests on them alone"
    diag = {
        "baseline": {"model": "ideal", "gap": 3.2},
        "noise_floor": 0.53,
        "final_gap": 1.61,
        "unexplained": True,
        "verdict_margin": {"rel_gap": 3.015, "se": 2.009, "n_heldout": 2, "limit": 3.0},
        "steps": [
            {"effect": "restitution", "model": "restitution", "params": {"e": 0.5},
             "gap": 2.0, "shrink": 0.3, "warnings": []},
            {"effect": "feedback", "model": "restitution+feedback", "params": {"e": 0.5},
             "gap": 1.61, "shrink": 0.2, "warnings": [step_warning]},
        ],
        "warnings": [f"restitution+feedback: {step_warning}", run_warning],
    }  # fmt: skip
    (run / "diagnosis.json").write_text(json.dumps(diag))
    blocks = diagnosis_blocks(tmp_path, "r", tmp_path / "captions.yaml")
    texts = [b["text"] for b in blocks if b["type"] == "text"]
    assert any("(3.02 +- 2 noise floors over 2 held-out Gamma steps; limit 3)" in t for t in texts)
    (listed,) = [t for t in texts if t.startswith("Warnings:")]
    assert run_warning in listed and step_warning not in listed


def _explained_diagnosis(**keys) -> dict:
    """A diagnosis JSON explained by nothing selected, with ``keys`` replaced or added."""
    base = {
        "baseline": {"model": "ideal", "gap": 3.2},
        "noise_floor": 0.5,
        "final_gap": 0.4,
        "unexplained": False,
        "steps": [],
        "warnings": [],
    }
    return base | keys


def test_diagnosis_text_says_whether_the_seeds_agree(tmp_path):
    """With ``seed_check`` (``--check-seeds``) the verdict's text says how many seeds were
    run and whether they agree; without it, nothing is said."""
    import json

    from bouncelab.report.content import diagnosis_blocks

    run = tmp_path / "runs" / "r"
    run.mkdir(parents=True)
    diag = _explained_diagnosis()

    def verdict_text(d):
        (run / "diagnosis.json").write_text(json.dumps(d))
        blocks = diagnosis_blocks(tmp_path, "r", tmp_path / "captions.yaml")
        return next(b["text"] for b in blocks if b["type"] == "text" and "Baseline" in b["text"])

    assert "seeds" not in verdict_text(diag)
    check = {"seeds": [0, 1, 2], "agree": True}
    assert "Diagnosed with 3 seeds: they agree." in verdict_text({**diag, "seed_check": check})
    check = {"seeds": [0, 1, 2], "agree": False, "reported_seed": 1, "reported_share": [2, 3]}
    text = verdict_text({**diag, "seed_check": check})
    expected = "they disagree; shown is seed 1's, the conclusion of 2 (see the warnings)."
    assert "Diagnosed with 3 seeds: " + expected in text
    # a retry (a first seed that left the gap unexplained)
    assert "Seed" not in verdict_text(diag)
    text = verdict_text({**diag, "retry": {"seeds": [0, 1], "reported_seed": 1}})
    assert "Seed 0 left the gap unexplained; shown is seed 1's diagnosis" in text
    text = verdict_text({**diag, "retry": {"seeds": [0, 1], "reported_seed": 0}})
    assert "Seed 0 left the gap unexplained, and so did 1 more seed(s)." in text
    # a retry that explained the run on a borderline verdict, not shown
    rows = [{"seed": 0, "unexplained": True}, {"seed": 1, "unexplained": False}]
    retry = {"seeds": [0, 1], "reported_seed": 0, "diagnoses": rows}
    text = verdict_text({**diag, "retry": retry})
    assert "seed 1 explained it only on a borderline verdict, not shown" in text


def test_accepted_effects_caption_shows_the_accelerometer_beside_the_drop_test(tmp_path):
    """The accelerometer's Gamma scale (``accel_calibration``) is in the caption of the
    accepted effects, after the drop-test calibration; nothing without it."""
    import json

    from bouncelab.report.content import diagnosis_blocks

    run = tmp_path / "runs" / "r"
    run.mkdir(parents=True)
    diag = _explained_diagnosis(
        steps=[{"effect": "gamma_scale", "model": "gamma_scale", "params": {"s": 0.931},
                "gap": 0.4, "shrink": 0.8, "warnings": []}],
        accel_calibration={"s": 0.9272, "s_ci": [0.9227, 0.9321], "n_steps": 5},
    )  # fmt: skip
    (run / "diagnosis.json").write_text(json.dumps(diag))

    def caption():
        blocks = diagnosis_blocks(tmp_path, "r", tmp_path / "captions.yaml")
        (table,) = [b for b in blocks if b.get("caption", "").startswith("Effects accepted")]
        return table["caption"]

    assert caption() == (
        "Effects accepted, in order (drop-test calibration: -; "
        "accelerometer: s = 0.9272 [0.9227, 0.9321])"
    )
    diag["accel_calibration"] |= {
        "harmonics": [{"k": 3, "a": 0.0802, "a_ci": [0.0797, 0.0813], "psi": 1.008}],
        "fixed": True,
    }
    (run / "diagnosis.json").write_text(json.dumps(diag))
    assert caption() == (
        "Effects accepted, in order (drop-test calibration: -; "
        "accelerometer: s = 0.9272 [0.9227, 0.9321], harmonic k = 3: "
        "a = 0.0802 [0.0797, 0.0813], psi = 1.008 (held in the fits))"
    )
    diag["accel_calibration"] |= {
        "harmonics": [],
        "armature": {"read": True, "f_ratio": 0.5145, "zeta": 0.03749, "rms_ratio": 2.7},
    }
    (run / "diagnosis.json").write_text(json.dumps(diag))
    assert caption().endswith(
        "armature ring-down: f_ratio = 0.5145, zeta = 0.03749 (held in the fits))"
    )
    diag["accel_calibration"]["armature"]["read"] = False
    (run / "diagnosis.json").write_text(json.dumps(diag))
    assert caption().endswith(", no armature ring-down read (held in the fits))")
    del diag["accel_calibration"]
    (run / "diagnosis.json").write_text(json.dumps(diag))
    assert caption() == "Effects accepted, in order (drop-test calibration: -)"
    # the drop run whose calibration it is, when the calibration names it
    diag["calibration"] = {"mu": 0.29, "restitution": 0.515, "run": "drop_test"}
    (run / "diagnosis.json").write_text(json.dumps(diag))
    assert caption().startswith("Effects accepted, in order (drop-test calibration of drop_test: ")


def test_blind_table_says_whether_the_misses_were_warned_about(tmp_path):
    """The blind validation's table counts the parameters by their warnings, per case set;
    a record scored before it had the counts shows "-"."""
    import json

    from bouncelab.report.content import blind_validation_blocks

    res = tmp_path / "results"
    (res / "figures").mkdir(parents=True)
    (res / "blind").mkdir()
    plt.figure().savefig(res / "figures" / "fig_blind_validation.png")
    plt.close("all")
    warned = {"n_params": 5, "n_outside_goal": 2, "n_outside_goal_warned": 2,
              "n_unwarned": 3, "n_unwarned_within_goal": 3}  # fmt: skip
    scores = {"by_set": {"validation": {"param_warnings": warned}, "development": {}}}
    (res / "blind" / "scores.json").write_text(json.dumps(scores))
    table = next(b for b in blind_validation_blocks(res, tmp_path) if b["type"] == "table")
    rows = {r[0]: r[1:] for r in table["rows"]}
    assert rows["parameters outside 15 % that the diagnosis warned about"] == ["2 of 2", "-", "all"]
    assert rows["parameters without a warning that are within 15 %"] == ["3 of 3", "-", "-"]


def test_a_run_the_config_leaves_undiagnosed_is_said_so_not_shown_stale(tmp_path):
    from bouncelab.report.content import diagnosis_blocks, not_diagnosed_by_config

    on = {"diagnosis": {"enabled": True, "skip": ["b"]}}
    assert not_diagnosed_by_config(on, "a") == ""
    assert "diagnosis.skip" in not_diagnosed_by_config(on, "b")
    off = {"diagnosis": {"enabled": False, "skip": []}}
    assert "diagnosis.enabled is false" in not_diagnosed_by_config(off, "a")
    # a diagnosis left from an earlier config is not read when the reason is given
    (tmp_path / "runs" / "b").mkdir(parents=True)
    (tmp_path / "runs" / "b" / "diagnosis.json").write_text("{not json a reader would take")
    (note,) = diagnosis_blocks(tmp_path, "b", tmp_path, not_diagnosed_by_config(on, "b"))
    assert note == {
        "type": "note",
        "text": "Gap diagnosis: not computed: the run is in diagnosis.skip of config/config.yaml.",
    }
    # no reason and no readable file: the note names the file and its log
    (note,) = diagnosis_blocks(tmp_path, "a", tmp_path)
    assert "runs/a/diagnosis.json" in note["text"] and "logs/diagnose/a.log" in note["text"]


def test_a_candidate_at_its_null_value_is_said_so(tmp_path):
    """A round-1 candidate whose search ended worse than the baseline is reported at its
    null value (``at_null``); the table says why its parameter reads 0, and a fitted one
    reads as before (reference: the JSON as written)."""
    import json

    from bouncelab.report.content import diagnosis_blocks

    run = tmp_path / "runs" / "r"
    run.mkdir(parents=True)
    cands = [
        {"effect": "friction", "params": {"mu": 0.12}, "gap": 0.2, "shrink": 0.4},
        {"effect": "restitution", "params": {"e": 0.0}, "gap": 0.3, "shrink": 0.0, "at_null": True},
    ]  # fmt: skip
    (run / "diagnosis.json").write_text(json.dumps(_explained_diagnosis(candidates=cands)))
    blocks = diagnosis_blocks(tmp_path, "r", tmp_path / "captions.yaml")
    (table,) = [b for b in blocks if "candidate" in b.get("caption", "")]
    fitted, null = (row[1] for row in table["rows"])
    assert "switched off" in null and "e = 0" in null
    assert "switched off" not in fitted
