"""Assemble the report's content (sections of blocks) from the pipeline's results.

Everything shown is read from files the workflow wrote under ``results/``: per-run
check verdicts, figures and their JSON data, calibrations, gap tables, energy budgets,
diagnoses. Paths follow the workflow's layout (``workflow/rules/*.smk``). A missing
piece gives a note in the report, never a crash: a run that failed its check is listed
with its error.
"""

from __future__ import annotations

import hashlib
import json
import math
import platform
import subprocess
from importlib import metadata
from pathlib import Path

import yaml

from bouncelab import __version__
from bouncelab.energy import seed_energy_reconstruction
from bouncelab.gap.diagnose import step_warning
from bouncelab.gap.seeds import borderline_retries
from bouncelab.report.claims import claims_table
from bouncelab.report.errata import ERRATA

#: figure file stem -> title shown in the report
FIGURE_TITLES = {
    "fig01_takeoff_line": "Fig. 1 - plate motion and the takeoff line",
    "fig02_bifurcation_ideal": "Fig. 2 - bifurcation diagram of the ideal model",
    "fig03_rig": "Fig. 3 - the rig",
    "fig04_accelerometer": "Fig. 4 - the accelerometer method",
    "fig05_continuity": "Fig. 5 - continuity signal and detected flights",
    "fig06_drop_test": "Fig. 6 - drop test",
    "fig07_bifurcation": "Fig. 7 - bifurcation diagrams, data and model",
    "fig08_return_maps": "Fig. 8 - return maps",
    "fig09_friction": "Fig. 9 - the model with and without friction",
    "fig10_harmonic": "Fig. 10 - the harmonic model",
    "gap_over_gamma": "Gap over Gamma",
    "energy_budget": "Energy budget",
    "fig_gap_diagnosis": "Gap before and after the diagnosed effects",
    "fig_blind_validation": "Blind validation of the diagnosis",
}

SWEEP_FIGURE_ORDER = [
    "fig03_rig",
    "fig05_continuity",
    "fig04_accelerometer",
    "fig07_bifurcation",
    "fig08_return_maps",
    "fig09_friction",
    "fig10_harmonic",
    "gap_over_gamma",
    "energy_budget",
]


def read_caption(captions_dir: Path, stem: str) -> tuple[str, str]:
    """(seed, here) text of a figure's caption file ``<stem>.rst`` ("Seed: ...", "Here: ...")."""
    path = captions_dir / f"{stem}.rst"
    if not path.is_file():
        return "", ""
    seed, here = "", ""
    for para in path.read_text().split("\n\n"):
        para = " ".join(para.split())
        if para.startswith("Seed:"):
            seed = para[len("Seed:") :].strip()
        elif para.startswith("Here:"):
            here = para[len("Here:") :].strip()
    return seed, here


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def figure_block(png: Path, stem: str, captions_dir: Path, label: str = "") -> dict | None:
    """A figure block from a PNG and its JSON, or None if the PNG is missing."""
    if not png.is_file():
        return None
    seed, here = read_caption(captions_dir, stem)
    data = _read_json(png.with_suffix(".json")) or {}
    summary = data.get("summary")
    ours = here + (f" {summary[0].upper()}{summary[1:]}" if summary else "")
    title = FIGURE_TITLES.get(stem, stem) + (f" ({label})" if label else "")
    return {
        "type": "figure",
        "id": f"{stem}-{label}" if label else stem,
        "title": title,
        "path": str(png),
        "seed": seed,
        "ours": ours,
    }


def fmt(x, digits: int = 4) -> str:
    """Number for a table cell: significant digits, '-' for missing."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def git_revision(repo: Path) -> str:
    """The checkout's revision (with '+dirty' for uncommitted changes), or 'unknown'."""

    def git(*args: str) -> str:
        done = subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, check=True)
        return done.stdout.strip()

    try:
        rev = git("rev-parse", "--short=12", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return rev + ("+dirty" if dirty else "")


def package_versions() -> list[list[str]]:
    """Rows (package, version) of what computed the results."""
    rows = [["python", platform.python_version()], ["bouncelab", __version__]]
    for name in (
        "numpy",
        "scipy",
        "numba",
        "pandas",
        "pyarrow",
        "matplotlib",
        "jinja2",
        "snakemake",
        "soundfile",
        "npTDMS",
        "typst",
    ):
        try:
            rows.append([name, metadata.version(name)])
        except metadata.PackageNotFoundError:
            rows.append([name, "not installed"])
    return rows


def file_hashes(raw_dir: Path, runs: list[str]) -> list[list[str]]:
    """Rows (file, size, sha256 prefix) of every input file of the given runs."""
    rows = []
    for run in runs:
        folder = raw_dir / run
        if not folder.is_dir():
            continue
        for p in sorted(folder.iterdir()):
            if p.is_file():
                h = hashlib.sha256()
                with p.open("rb") as fh:
                    for chunk in iter(lambda: fh.read(1 << 20), b""):
                        h.update(chunk)
                rows.append([f"{run}/{p.name}", str(p.stat().st_size), h.hexdigest()[:16]])
    return rows


def runs_table(checks: dict[str, dict]) -> dict:
    """Overview of every run: kind, source, duration, steps, Gamma range, gaps, status."""
    rows = []
    for run, v in checks.items():
        info = v.get("info") or {}
        gaps = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in info.get("gamma_gaps") or []) or "-"
        rng = (
            f"{info['gamma_min']:g}-{info['gamma_max']:g}"
            if info.get("gamma_min") is not None
            else "-"
        )
        rows.append(
            [
                run,
                info.get("kind", "?"),
                info.get("source") or "-",
                fmt(info.get("duration_s"), 4),
                str(info.get("n_steps", "-")) if info.get("kind") == "sweep" else "-",
                rng if info.get("kind") == "sweep" else "-",
                gaps if info.get("kind") == "sweep" else "-",
                "ok" if v.get("ok") else "FAILED",
            ]
        )
    return {
        "type": "table",
        "caption": "Runs found under raw/",
        "header": ["run", "kind", "source", "duration (s)", "steps", "Gamma", "gaps", "check"],
        "rows": rows,
    }


def calibration_rows(results: Path, drops: list[str]) -> list[list[str]]:
    """One row per calibrated drop run: mu and e with their intervals, the bounces used,
    the calibration's warnings ("-": none)."""
    rows = []
    for run in drops:
        cal = _read_json(results / "runs" / run / "calibration.json")
        if not cal:
            continue
        rows.append(
            [
                run,
                f"{cal['mu']:.4f} [{cal['mu_ci'][0]:.4f}, {cal['mu_ci'][1]:.4f}]",
                f"{cal['restitution']:.4f} "
                f"[{cal['restitution_ci'][0]:.4f}, {cal['restitution_ci'][1]:.4f}]",
                str(cal["n_bounces"]),
                "; ".join(map(str, cal.get("warnings") or [])) or "-",
            ]
        )
    return rows


def _seed_check_text(check: dict | None) -> str:
    """A sentence on the diagnosis's seed check (``--check-seeds``), or "" without one;
    what each seed concluded is in the run's warnings."""
    if not check:
        return ""
    n = len(check["seeds"])
    if check["agree"]:
        return f" Diagnosed with {n} seeds: they agree."
    k = check["reported_share"][0]
    return (
        f" Diagnosed with {n} seeds: they disagree; shown is seed "
        f"{check['reported_seed']}'s, the conclusion of {k} (see the warnings)."
    )


def _retry_text(retry: dict | None) -> str:
    """A sentence on the diagnosis's retries (a first seed that left the gap unexplained),
    or "" without any."""
    if not retry:
        return ""
    first, shown = retry["seeds"][0], retry["reported_seed"]
    if shown == first:
        n = len(retry["seeds"]) - 1
        border = borderline_retries(retry)
        if border:
            seeds = ", ".join(str(r["seed"]) for r in border)
            return (
                f" Seed {first} left the gap unexplained; {n} more seed(s) tried, seed "
                f"{seeds} explained it only on a borderline verdict, not shown (see the "
                "warnings)."
            )
        return f" Seed {first} left the gap unexplained, and so did {n} more seed(s)."
    return (
        f" Seed {first} left the gap unexplained; shown is seed {shown}'s diagnosis, which "
        "explains it (see the warnings)."
    )


def _params_text(params: dict, ci: dict | None = None) -> str:
    """``mu = 0.29 [0.27, 0.31], e = 0.5`` from a parameter dict and optional intervals."""
    parts = []
    for k, v in sorted((params or {}).items()):
        if not isinstance(v, (int, float)):
            continue
        text = f"{k} = {v:.4g}"
        lohi = (ci or {}).get(k)
        if lohi and None not in lohi:
            text += f" [{lohi[0]:.4g}, {lohi[1]:.4g}]"
        parts.append(text)
    return ", ".join(parts) or "-"


def _accel_text(accel: dict | None) -> str:
    """The accelerometer's readings (Gamma scale, harmonics, the armature's ring-down)
    for the accepted effects' caption, or ''."""
    if not accel:
        return ""
    text = "; accelerometer: " + _params_text({"s": accel.get("s")}, {"s": accel.get("s_ci")})
    for h in accel.get("harmonics") or []:
        text += f", harmonic k = {h['k']:g}: " + _params_text(
            {"a": h["a"], "psi": h["psi"]}, {"a": h["a_ci"]}
        )
    arm = accel.get("armature")
    if arm and arm.get("read"):
        text += ", armature ring-down: " + _params_text(
            {"f_ratio": arm["f_ratio"], "zeta": arm["zeta"]}, {}
        )
    elif arm is not None:
        text += ", no armature ring-down read"
    if accel.get("fixed"):
        text += " (held in the fits)"
    return text


def not_diagnosed_by_config(config: dict, run: str) -> str:
    """Why the workflow's config leaves a sweep run undiagnosed ('' when it does not):
    ``diagnosis.enabled`` false, or the run in ``diagnosis.skip``. Read from the config
    rather than from a missing file, so a diagnosis left over from an earlier config is
    not shown."""
    diag = config.get("diagnosis") or {}
    if not diag.get("enabled", True):
        return "diagnosis.enabled is false in config/config.yaml"
    if run in (diag.get("skip") or []):
        return "the run is in diagnosis.skip of config/config.yaml"
    return ""


def diagnosis_blocks(results: Path, run: str, captions: Path, no_diagnosis: str = "") -> list[dict]:
    """The gap diagnosis of a sweep run: figure, verdict, candidates, accepted effects,
    regions; or a note saying why it has not been computed (``no_diagnosis``: the
    check's reason, e.g. too few Gamma steps)."""
    if no_diagnosis:
        return [{"type": "note", "text": f"Gap diagnosis: not computed: {no_diagnosis}."}]
    diag = _read_json(results / "runs" / run / "diagnosis.json")
    if not diag:
        return [
            {
                "type": "note",
                "text": f"Gap diagnosis: not computed for this run (no readable "
                f"runs/{run}/diagnosis.json; its log is logs/diagnose/{run}.log).",
            }
        ]
    blocks = []
    fig = figure_block(
        results / "figures" / run / "fig_gap_diagnosis.png", "fig_gap_diagnosis", captions, run
    )
    if fig:
        blocks.append(fig)
    base = diag["baseline"]
    floor = diag.get("noise_floor")
    verdict = (
        "What remains is clearly above the noise floor: none of the candidate effects "
        "explains it (unexplained)."
        if diag.get("unexplained")
        else "What remains is within the noise floor (explained)."
    )
    reasons = diag.get("unexplained_reasons") or []
    margin = diag.get("verdict_margin") or {}
    margin_text = (
        f" ({fmt(margin['rel_gap'], 3)} +- {fmt(margin['se'], 2)} noise floors over "
        f"{margin['n_heldout']} held-out Gamma steps; limit {fmt(margin['limit'])})"
        if margin.get("se") is not None
        else ""
    )
    blocks.append(
        {
            "type": "text",
            "text": (
                f"Baseline model {base['model']}: gap {fmt(base['gap'])} rad against a noise "
                f"floor of {fmt(floor)} rad. Effects accepted, in order: "
                f"{', '.join(diag.get('selected') or []) or 'none'}; final gap "
                f"{fmt(diag.get('final_gap'))} rad{margin_text}. {verdict}"
                + (f" Why: {'; '.join(map(str, reasons))}." if reasons else "")
                + _seed_check_text(diag.get("seed_check"))
                + _retry_text(diag.get("retry"))
            ),
        }
    )
    # the selection's and the verdict's own warnings (the steps' are in the table below)
    of_steps = {
        step_warning(s["model"], w) for s in diag.get("steps", []) for w in s.get("warnings") or []
    }
    run_warnings = [w for w in diag.get("warnings") or [] if w not in of_steps]
    if run_warnings:
        blocks.append(
            {"type": "text", "text": "Warnings: " + "; ".join(map(str, run_warnings)) + "."}
        )
    cal = diag.get("calibration") or {}
    cal_of = f" of {cal['run']}" if cal.get("run") else ""  # the drop run, where named
    cal_text = (
        _params_text(
            {"mu": cal.get("mu"), "e": cal.get("restitution")},
            {"mu": cal.get("mu_ci"), "e": cal.get("restitution_ci")},
        )
        if cal
        else "-"
    )
    rows = [
        [
            s["effect"],
            _params_text(s.get("params", {}), s.get("params_ci"))
            + (  # the same impacts in the other convention (docs/diagnosis.md)
                f"; e_rigid_plate = {s['e_rigid_plate']:.4g}" if "e_rigid_plate" in s else ""
            ),
            fmt(s["gap"]),
            fmt(s["shrink"]),
            "; ".join(map(str, s.get("warnings") or [])) or "-",
        ]
        for s in diag.get("steps", [])
    ]
    if rows:
        blocks.append(
            {
                "type": "table",
                "caption": f"Effects accepted, in order (drop-test calibration{cal_of}: "
                + cal_text
                + _accel_text(diag.get("accel_calibration"))
                + ")",
                "header": [
                    "effect",
                    "fitted parameters [interval]",
                    "gap (rad)",
                    "shrink",
                    "warnings",
                ],
                "rows": rows,
            }
        )
    cand = [
        [
            c["effect"],
            _params_text(c.get("params", {}))
            + (
                "; its search ended worse than the baseline: shown switched off"
                if c.get("at_null")
                else ""
            ),
            fmt(c["gap"]),
            fmt(c["shrink"]),
        ]
        for c in diag.get("candidates", [])
    ]
    if cand:
        blocks.append(
            {
                "type": "table",
                "caption": "Each candidate effect added alone to the baseline and refitted "
                "(gap on held-out Gamma steps)",
                "header": ["effect", "fitted parameters", "gap (rad)", "shrink"],
                "rows": cand,
            }
        )
    regions = [
        [
            f"{fmt(r['gamma_min'])} - {fmt(r['gamma_max'])}",
            fmt(r["gap"]),
            r.get("explained_by") or "-",
        ]
        for r in diag.get("regions", [])
    ]
    if regions:
        blocks.append(
            {
                "type": "table",
                "caption": "Where the gap lies: regions over Gamma",
                "header": ["Gamma", "gap (rad)", "explained by"],
                "rows": regions,
            }
        )
    return blocks


def _count(summary: dict, part: str, whole: str) -> str:
    """``"part of whole"`` from a blind summary's ``param_warnings`` ("-" in a record
    scored before it had them)."""
    w = summary.get("param_warnings") or {}
    return f"{w[part]} of {w[whole]}" if part in w and whole in w else "-"


def blind_validation_blocks(results: Path, captions: Path) -> list[dict]:
    """The blind validation of the diagnosis, when the workflow computed it."""
    png = results / "figures" / "fig_blind_validation.png"
    scores = _read_json(results / "blind" / "scores.json")
    if not png.is_file() or not scores:
        return [
            {
                "type": "note",
                "text": "The blind validation was not run in this build (about 25 minutes on "
                "2 cores): run snakemake --cores 2 --configfile "
                "config/with_blind_validation.yaml to include it. docs/diagnosis.md records "
                "its last measured results.",
            }
        ]
    blocks = [figure_block(png, "fig_blind_validation", captions)]
    # one column per case set: the validation set (written after the design was frozen)
    # is the evidence; the development set was seen while designing (docs/diagnosis.md)
    sets = scores.get("by_set") or {"all cases": scores.get("summary") or {}}
    names = [k for k in ("validation", "development") if k in sets] or list(sets)

    def row(label, value, goal):
        return [label, *(value(sets[k]) for k in names), goal]

    rows = [
        row("single-effect cases with the top effect right",
            lambda m: f"{fmt(m.get('top_effect_right'))} of {m.get('n_single')}", "0.9"),
        row("single-effect cases with nothing else selected",
            lambda m: f"{m.get('single_set_right', '-')} of {m.get('n_single')}", "-"),
        row("false alarms on null cases",
            lambda m: f"{m.get('null_false_alarms')} of {m.get('n_null')}", "0"),
        row("out-of-library cases flagged unexplained",
            lambda m: f"{m.get('outside_flagged')} of {m.get('n_outside')}", "all"),
        row("parameters within 15 %", lambda m: fmt(m.get("param_within_goal")), "1"),
        row("true parameters inside the reported interval",
            lambda m: f"{m.get('n_params_in_interval', '-')} of {m.get('n_params_scored', '-')}",
            "-"),
        row("parameters outside 15 % that the diagnosis warned about",
            lambda m: _count(m, "n_outside_goal_warned", "n_outside_goal"), "all"),
        row("parameters without a warning that are within 15 %",
            lambda m: _count(m, "n_unwarned_within_goal", "n_unwarned"), "-"),
    ]  # fmt: skip

    def errors(m, name):
        return ", ".join(fmt(e, 2) for e in (m.get("param_errors") or {}).get(name, [])) or "-"

    params = sorted({p for k in names for p in (sets[k].get("param_errors") or {})})
    for name in params:
        rows.append(row(f"relative error of {name}", lambda m, n=name: errors(m, n), "< 0.15"))
    for k in names:
        for name, c in sorted((sets[k].get("combinations") or {}).items()):
            rows.append(
                [
                    f"combination {name} ({k}): {' + '.join(c.get('true', []))}",
                    *(
                        ("selected " + (" + ".join(c.get("selected", [])) or "nothing"))
                        if j == k
                        else ""
                        for j in names
                    ),
                    "the same set",
                ]
            )
    blocks.append(
        {
            "type": "table",
            "caption": "Blind validation against its goals, per case set",
            "header": ["measure", *(f"{k} set" for k in names), "goal"],
            "rows": rows,
        }
    )
    return [b for b in blocks if b]


def build_context(
    results_dir,
    raw_dir,
    runs: list[str],
    config: dict,
    captions_dir,
    bad_names: list[str] = (),
    repo_dir=".",
) -> dict:
    """The full report context for :mod:`bouncelab.report.render`."""
    results = Path(results_dir)
    raw = Path(raw_dir)
    captions = Path(captions_dir)
    figs = results / "figures"
    checks = {
        run: _read_json(results / "runs" / run / "check.json")
        or {"ok": False, "error": "check not run"}
        for run in runs
    }
    ok_runs = [r for r, v in checks.items() if v.get("ok")]
    kind = {r: (checks[r].get("info") or {}).get("kind") for r in ok_runs}
    sweeps = [r for r in ok_runs if kind[r] == "sweep"]
    drops = [r for r in ok_runs if kind[r] == "drop"]
    failed = [(r, v.get("error", "")) for r, v in checks.items() if not v.get("ok")]
    failed += [
        (name, "folder name outside the pattern [A-Za-z0-9][A-Za-z0-9_.-]*") for name in bad_names
    ]

    sections = []
    sections.append(
        {
            "id": "summary",
            "title": "Summary",
            "blocks": [
                {
                    "type": "text",
                    "text": (
                        "This report rebuilds the figures of the seed paper (a laboratory "
                        "investigation of the completely inelastic bouncing ball) from raw "
                        f"continuity recordings: {len(sweeps)} sweep run(s) and {len(drops)} "
                        f"drop run(s) under raw/, with {len(failed)} run(s) that could not be "
                        "used. Each model variant is simulated under each run's own protocol "
                        "(its Gamma steps, drive frequency and settle cycles, the state carried "
                        "over from step to step) and compared with the measured flights."
                    ),
                },
                runs_table(checks),
            ],
        }
    )
    sections.append(
        {
            "id": "claims",
            "title": "The seed's claims beside our values",
            "blocks": [claims_table(results, sweeps, drops, checks)],
        }
    )
    sections.append(
        {
            "id": "errata",
            "title": "Errata: the seed's equations, corrected",
            "blocks": [
                {
                    "type": "text",
                    "text": "The seed's equations carry typos; the code uses the corrected "
                    "forms below (nondimensional: phase phi = omega t, height chi = x omega^2/g, "
                    "Gamma = A omega^2/g).",
                },
                {
                    "type": "table",
                    "caption": "Equations as printed in the seed and as coded here",
                    "header": ["seed", "corrected", "why"],
                    "rows": [[e["seed"], e["corrected"], e["note"]] for e in ERRATA],
                },
            ],
        }
    )
    model_blocks = [
        figure_block(figs / f"{stem}.png", stem, captions)
        for stem in ("fig01_takeoff_line", "fig02_bifurcation_ideal")
    ]
    sections.append({"id": "model", "title": "The model", "blocks": [b for b in model_blocks if b]})

    meas = []
    for run in drops:
        for stem in ("fig03_rig", "fig06_drop_test"):
            b = figure_block(figs / run / f"{stem}.png", stem, captions, run)
            if b:
                meas.append(b)
    cal_rows = calibration_rows(results, drops)
    if cal_rows:
        meas.append(
            {
                "type": "table",
                "caption": "Drop-test calibration (95 % bootstrap intervals)",
                "header": ["run", "friction mu", "restitution e", "bounces", "warnings"],
                "rows": cal_rows,
            }
        )
    if not drops:
        meas.append({"type": "note", "text": "No drop run: models use the seed's mu and e."})
    sections.append({"id": "calibration", "title": "Drop tests and calibration", "blocks": meas})

    for run in sweeps:
        blocks = []
        info = checks[run].get("info") or {}
        blocks.append(
            {
                "type": "text",
                "text": (
                    f"Run {run}: {info.get('n_steps', '?')} Gamma steps from "
                    f"{fmt(info.get('gamma_min'))} to {fmt(info.get('gamma_max'))} at "
                    f"{fmt(info.get('drive_frequency_hz'))} Hz, "
                    f"{fmt(info.get('duration_s'))} s recorded "
                    f"({info.get('source') or 'source not stated'})."
                ),
            }
        )
        for stem in SWEEP_FIGURE_ORDER:
            b = figure_block(figs / run / f"{stem}.png", stem, captions, run)
            if b:
                blocks.append(b)
        blocks.append({"type": "heading", "id": f"diag-{run}", "text": "Gap diagnosis"})
        why_not = checks[run].get("no_diagnosis", "") or not_diagnosed_by_config(config, run)
        blocks.extend(diagnosis_blocks(results, run, captions, why_not))
        sections.append({"id": f"run-{run}", "title": f"Sweep run {run}", "blocks": blocks})

    sections.append(
        {
            "id": "validation",
            "title": "Validation of the gap diagnosis on withheld effects",
            "blocks": blind_validation_blocks(results, captions),
        }
    )

    energy_rows = [
        [r["quantity"], fmt(r["seed_j"]), fmt(r["value_j"]), r["assumption"]]
        for r in seed_energy_reconstruction()
    ]
    sections.append(
        {
            "id": "energy",
            "title": "The seed's energy numbers, reconstructed",
            "blocks": [
                {
                    "type": "text",
                    "text": (
                        "The seed gives two numbers at Gamma = 3.4 for a flight of T = 0.11 s "
                        "(m = 249 g, mu = 0.29, e = 0.515) without a derivation. Each row is one "
                        "reading of it, computed here (g = 9.81 m/s^2). The friction number is "
                        "reproduced by the difference in landing kinetic energy between an ideal "
                        "flight and a friction flight of the same duration; the energy friction "
                        "actually dissipates in that flight (mu m g times the path) is larger. "
                        "The restitution number is close to the rebound energy of a fall lasting "
                        "half the flight; it is energy the inelastic model would not return, and "
                        "it is indeed smaller than the friction loss, as the seed says."
                    ),
                },
                {
                    "type": "table",
                    "caption": "Seed energy numbers (J) and their reconstructions",
                    "header": ["quantity", "seed (J)", "reconstructed (J)", "assumption"],
                    "rows": energy_rows,
                },
            ],
        }
    )

    fail_blocks = (
        [
            {
                "type": "table",
                "caption": "Runs that could not be used",
                "header": ["run", "error"],
                "rows": [[r, e] for r, e in failed],
            }
        ]
        if failed
        else [{"type": "text", "text": "Every run under raw/ passed its check."}]
    )
    sections.append({"id": "failed", "title": "Failed runs", "blocks": fail_blocks})

    sections.append(
        {
            "id": "provenance",
            "title": "Provenance",
            "blocks": [
                {
                    "type": "table",
                    "caption": "Software",
                    "header": ["package", "version"],
                    "rows": package_versions(),
                },
                {
                    "type": "table",
                    "caption": "Input files (sha256, first 16 hex digits)",
                    "header": ["file", "bytes", "sha256"],
                    "rows": file_hashes(raw, runs),
                },
                {"type": "heading", "id": "prov-config", "text": "Configuration"},
                {"type": "code", "text": yaml.safe_dump(config, sort_keys=True)},
            ],
        }
    )
    return {
        "title": "bouncelab report",
        "subtitle": "The bouncing ball on a vibrating plate: data, models and the gap between them",
        "version": __version__,
        "git_revision": git_revision(Path(repo_dir)),
        "sections": sections,
    }
