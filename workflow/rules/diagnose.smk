# Stage 3b: the sim-to-real gap diagnosis of each sweep run (which effect, how far,
# where), and the blind validation of the diagnosis on rig recordings whose effects it
# is not told (a target of its own: `snakemake --cores 2 blind_validation`).


rule diagnose:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        # read beside the flights for the drive channel's measured frequency
        qc=f"{RES}/runs/{{run}}/flights.qc.parquet",
        calibration=calibration_input,
    output:
        report(
            f"{RES}/runs/{{run}}/diagnosis.json",
            caption="../report/diagnosis.rst",
            category="Gap diagnosis",
            subcategory="{run}",
        ),
    log:
        f"{RES}/logs/diagnose/{{run}}.log",
    benchmark:
        f"{RES}/benchmarks/diagnose/{{run}}.tsv"
    conda:
        "../envs/bouncelab.yaml"
    threads: 2
    resources:
        mem_mb=3000,
    params:
        run_dir=lambda wc: str(RAW / wc.run),
        calibration=lambda wc, input: (
            f"--calibration {input.calibration[0]}" if input.calibration else ""
        ),
        baseline=config["diagnosis"]["baseline"],
        seed=config["diagnosis"]["seed"],
        check_seeds=config["diagnosis"]["check_seeds"],
        retries=config["diagnosis"]["retries"],
        repeat_limit=config["diagnosis"]["repeat_limit_rad"],
        fix_accel=lambda wc: (
            "--fix-accel"
            if config["diagnosis"]["fix_accel"] and wc.run in ACCEL_G_RUNS
            else ""
        ),
    shell:
        "bouncelab diagnose {params.run_dir:q} --flights {input.flights:q} "
        "{params.calibration} --baseline {params.baseline} --seed {params.seed} "
        "--check-seeds {params.check_seeds} --retries {params.retries} "
        "--repeat-limit {params.repeat_limit} {params.fix_accel} "
        "--workers {threads} -o {output:q} > {log:q} 2>&1"


rule blind_validation:
    input:
        cases="config/blind/cases.yaml",
    output:
        scores=report(
            f"{RES}/blind/scores.json",
            caption="../report/blind_validation.rst",
            category="Gap diagnosis",
        ),
    log:
        f"{RES}/logs/blind_validation.log",
    benchmark:
        f"{RES}/benchmarks/blind_validation.tsv"
    conda:
        "../envs/bouncelab.yaml"
    threads: 2
    params:
        out=lambda wildcards, output: str(Path(output.scores).parent),
        seed=config["diagnosis"]["seed"],
    shell:
        "python -m bouncelab.gap.blind --out {params.out:q} --cases {input.cases:q} "
        "--seed {params.seed} --workers {threads} > {log:q} 2>&1"
