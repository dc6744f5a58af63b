"""How the workflow behaves: no-op reruns, determinism, dropped-in and broken runs, lint."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import zipfile

from .conftest import REPO, SKIPPED_DIAGNOSES, copy_project, snakemake, tree_hashes

JOB_RE = re.compile(
    r"^(?:local)?(?:rule|checkpoint) (\w+):\n(?:    .*\n)*?    wildcards: (.*)$", re.M
)
ANY_JOB_RE = re.compile(r"^(?:local)?(?:rule|checkpoint) (\w+):$", re.M)


def executed_jobs(output: str) -> list[tuple[str, str]]:
    """(rule, wildcards) of every job a snakemake run reported, '' without wildcards."""
    jobs = []
    for block in re.split(r"\n(?=\[|(?:local)?(?:rule|checkpoint) \w+:\n)", output):
        m = ANY_JOB_RE.search(block)
        if not m:
            continue
        w = re.search(r"^    wildcards: (.*)$", block, re.M)
        jobs.append((m.group(1), w.group(1) if w else ""))
    return jobs


def test_rerun_with_nothing_changed_does_nothing(workflow_dir):
    out = snakemake(workflow_dir, "-n")
    assert "Nothing to be done" in out.stdout + out.stderr


def test_snakemake_report_packs_the_marked_outputs(workflow_dir, tmp_path):
    # every output marked report() (figures with captions, gap tables, diagnoses)
    zip_path = tmp_path / "snakemake-report.zip"
    snakemake(workflow_dir, "--report", str(zip_path))
    with zipfile.ZipFile(zip_path) as z:
        names = z.namelist()
    assert any(n.endswith("report.html") for n in names)
    assert sum(n.endswith(".png") for n in names) >= 20


def test_two_runs_give_identical_simulations_and_figures(workflow_dir):
    # one sweep run's simulations, comparisons and figures, the model-only figures and the
    # report are made again from the same inputs and must be byte-identical (Snakemake
    # rebuilds missing intermediates only for a missing product, so the report goes too)
    res = workflow_dir / "results"
    run = "sweep_g0-4"
    redo = [res / "figures" / run, res / "runs" / run / "sim", res / "report"]
    redo += [res / "runs" / run / name for name in ("compare.parquet", "energy.parquet")]
    redo += sorted((res / "figures").glob("fig0*.*"))

    def hashes():
        runs = tree_hashes(res / "runs", suffixes=(".parquet",))
        report = tree_hashes(res / "report", suffixes=(".html", ".pdf"))
        return (
            tree_hashes(res / "figures")
            | {f"runs/{k}": v for k, v in runs.items()}
            | {f"report/{k}": v for k, v in report.items()}
        )

    before = hashes()
    for path in redo:
        shutil.rmtree(path) if path.is_dir() else path.unlink()
    snakemake(workflow_dir)
    assert hashes() == before


def write_silent_sweep(run_dir):
    """A sweep run (NPZ, 2 s at 20 kHz, Gamma 2 and 3) whose continuity channel is noise
    about one level: a disconnected circuit, no contact to find."""
    import numpy as np

    run_dir.mkdir(parents=True)
    noise = 2.5 + 0.02 * np.random.default_rng(5).standard_normal(40_000)
    np.savez_compressed(run_dir / "rec.npz", continuity=noise)
    (run_dir / "run.yaml").write_text(
        "format_version: 1\nkind: sweep\nrecording: rec.npz\nsample_rate_hz: 20000\n"
        "channels: {continuity: continuity}\ndrive_frequency_hz: 30\n"
        "gamma_steps:\n- {t_s: 0.0, gamma: 2.0}\n- {t_s: 1.0, gamma: 3.0}\n"
    )


def test_dropped_in_run_and_broken_run(project_copy):
    # the built project, copied: up to date before anything is dropped in
    work = project_copy
    dry = snakemake(work, "-n")
    assert "Nothing to be done" in dry.stdout + dry.stderr
    # drop in a new sweep: only its own jobs and the report run
    shutil.copytree(REPO / "raw" / "accel_g2-4", work / "raw" / "new_sweep")
    out = snakemake(work)
    jobs = executed_jobs(out.stdout + out.stderr)
    assert jobs, out.stderr[-2000:]
    foreign = [(r, w) for r, w in jobs if w and "run=new_sweep" not in w]
    assert not foreign, f"jobs of other runs reran: {foreign}"
    unnamed = {r for r, w in jobs if not w}
    assert unnamed <= {"report", "all"}, unnamed
    assert ("simulate", "run=new_sweep, variant=ideal") in jobs
    assert ("diagnose", "run=new_sweep") in jobs  # diagnosed: not in diagnosis.skip
    html = (work / "results" / "report" / "report.html").read_text()
    assert 'id="run-new_sweep"' in html

    # drop in a drop test of another body, first by name and sharing no prefix: it must not
    # take over the sweeps' calibration (it did: every sweep's models and diagnosis reran)
    other = work / "raw" / "a_lighter_body_drop"
    shutil.copytree(REPO / "raw" / "drop_test", other)
    spec = (other / "run.yaml").read_text()
    assert "mass_kg: 0.249" in spec
    (other / "run.yaml").write_text(spec.replace("mass_kg: 0.249", "mass_kg: 0.2"))
    out = snakemake(work)
    jobs = executed_jobs(out.stdout + out.stderr)
    foreign = [(r, w) for r, w in jobs if w and "run=a_lighter_body_drop" not in w]
    assert not foreign, f"jobs of other runs reran: {foreign}"
    assert ("calibrate", "run=a_lighter_body_drop") in jobs
    shutil.rmtree(other)

    # broken runs: their own jobs fail with their errors, the rest and the report build.
    # A truncated recording; a drop test of the sweeps' body, first by name, without a
    # required key (it took over the sweeps' calibration, which fell back to the
    # defaults); a sweep whose continuity channel holds no contacts (it passed the check,
    # and the report waited for its products: a black-box probe)
    broken = work / "raw" / "broken_run"
    shutil.copytree(REPO / "raw" / "accel_g2-4", broken)
    rec = next(p for p in broken.iterdir() if p.suffix == ".flac")
    rec.write_bytes(rec.read_bytes()[:2000])  # truncated audio
    keyless = work / "raw" / "a_broken_drop"
    shutil.copytree(REPO / "raw" / "drop_test", keyless)
    spec = (keyless / "run.yaml").read_text()
    (keyless / "run.yaml").write_text(re.sub(r"(?m)^sample_rate_hz:.*\n", "", spec))
    write_silent_sweep(work / "raw" / "silent_sweep")
    out = snakemake(work, "--keep-going", check=False)
    assert out.returncode != 0
    jobs = executed_jobs(out.stdout + out.stderr)
    mine = ("run=broken_run", "run=a_broken_drop", "run=silent_sweep")
    foreign = [(r, w) for r, w in jobs if w and not w.startswith(mine)]
    assert not foreign, f"jobs of other runs reran: {foreign}"
    log = (work / "results" / "logs" / "extract" / "broken_run.log").read_text()
    assert log.startswith("error:") and "broken_run" in log
    log = (work / "results" / "logs" / "extract" / "silent_sweep.log").read_text()
    assert log.startswith("error:") and "no contacts found" in log
    html = (work / "results" / "report" / "report.html").read_text()
    assert "Runs that could not be used" in html
    for name in ("broken_run", "a_broken_drop", "silent_sweep"):
        assert name in html, name
    assert "required key &#39;sample_rate_hz&#39; is missing" in html or (
        "required key 'sample_rate_hz' is missing" in html
    )
    assert 'id="run-new_sweep"' in html
    shutil.rmtree(keyless)
    shutil.rmtree(work / "raw" / "silent_sweep")

    # a sweep too short to diagnose (2 Gamma steps): every product but the diagnosis,
    # and the report says why (before, its diagnose job failed and stopped the report)
    short = work / "raw" / "short_sweep"
    shutil.copytree(REPO / "raw" / "accel_g2-4", short)
    spec = (short / "run.yaml").read_text().splitlines()
    steps = [i for i, line in enumerate(spec) if line.startswith("- {t_s:")]
    (short / "run.yaml").write_text("\n".join(spec[: steps[2]] + spec[steps[-1] + 1 :]) + "\n")
    snakemake(work, "--keep-going", check=False)
    assert (work / "results" / "runs" / "short_sweep" / "compare.parquet").exists()
    assert not (work / "results" / "runs" / "short_sweep" / "diagnosis.json").exists()
    html = (work / "results" / "report" / "report.html").read_text()
    assert 'id="run-short_sweep"' in html
    assert "diagnosis needs at least 3 Gamma steps, the run has 2" in html


def test_a_run_in_diagnosis_skip_gets_every_product_but_the_diagnosis(workflow_dir):
    # the test projects skip raw/sweep_g0-8's diagnosis (conftest); the other sweeps have one
    res = workflow_dir / "results"
    html = (res / "report" / "report.html").read_text()
    for run in SKIPPED_DIAGNOSES:
        assert (res / "runs" / run / "compare.parquet").is_file()
        assert (res / "figures" / run / "gap_over_gamma.png").is_file()
        assert not (res / "runs" / run / "diagnosis.json").exists()
        assert not (res / "figures" / run / "fig_gap_diagnosis.png").exists()
    assert html.count("the run is in diagnosis.skip of config/config.yaml") == len(
        SKIPPED_DIAGNOSES
    )
    for run in ("sweep_g0-4", "accel_g2-4"):
        assert (res / "runs" / run / "diagnosis.json").is_file()


def test_a_misspelt_id_in_diagnosis_skip_is_one_warning(tmp_path):
    work = copy_project(tmp_path / "project", raw_runs=["accel_g2-4"])
    cfg = work / "config" / "config.yaml"
    text = cfg.read_text()
    cfg.write_text(text.replace("  skip: [sweep_g0-8]", "  skip: [accel_g2_4, accel_g2-4]"))
    out = snakemake(work, "-n")
    said = [line for line in out.stderr.splitlines() if "diagnosis.skip" in line]
    assert said == ["warning: diagnosis.skip in the config names no sweep run of raw/: accel_g2_4"]


def test_snakemake_lint_and_snakefmt_are_clean():
    lint = subprocess.run(
        [sys.executable, "-m", "snakemake", "--lint", "--cores", "1"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=False,
    )
    assert lint.returncode == 0, lint.stdout[-3000:] + lint.stderr[-3000:]
    assert "Lints for" not in lint.stdout + lint.stderr
    fmt = subprocess.run(
        [sys.executable, "-m", "snakefmt", "--check", "Snakefile", "workflow/rules"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=False,
    )
    assert fmt.returncode == 0, fmt.stdout + fmt.stderr
