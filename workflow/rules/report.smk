# Stage 5: the report, HTML (self-contained) and PDF (typst), from one set of jinja2
# templates under report/. It depends only on runs whose check passed; the others are
# listed in it with their error.


rule report:
    input:
        checks=expand(f"{RES}/runs/{{run}}/check.json", run=list(RUNS)),
        products=products_of_valid_runs,
        model_figures=[
            f"{FIG}/fig01_takeoff_line.png",
            f"{FIG}/fig02_bifurcation_ideal.png",
        ],
        # the blind validation takes long: in the report only when the config asks
        blind=(
            [f"{FIG}/fig_blind_validation.png"]
            if config["diagnosis"]["blind_in_report"]
            else []
        ),
        templates=sorted(str(p) for p in Path("report").rglob("*") if p.is_file()),
        config="config/config.yaml",
    output:
        html=f"{RES}/report/report.html",
        pdf=f"{RES}/report/report.pdf",
    log:
        f"{RES}/logs/report.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        raw_dir=str(RAW),
        # the results folder, from the output path: <results>/report/report.html
        results_dir=lambda wildcards, output: str(Path(output.html).parents[1]),
        runs=list(RUNS),
        bad_names=BAD_NAMES,
        config=config,
    script:
        "../scripts/build_report.py"
