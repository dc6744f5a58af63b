# Stage 1: each raw run is checked, its flights extracted, drop runs calibrated.


checkpoint check_run:
    input:
        run_files,
    output:
        f"{RES}/runs/{{run}}/check.json",
    log:
        f"{RES}/logs/check_run/{{run}}.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        run_dir=lambda wc: str(RAW / wc.run),
    script:
        "../scripts/check_run.py"


rule extract:
    input:
        run_files,
    output:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        qc=f"{RES}/runs/{{run}}/flights.qc.parquet",
    log:
        f"{RES}/logs/extract/{{run}}.log",
    benchmark:
        f"{RES}/benchmarks/extract/{{run}}.tsv"
    conda:
        "../envs/bouncelab.yaml"
    threads: 1
    resources:
        mem_mb=2000,
    params:
        run_dir=lambda wc: str(RAW / wc.run),
    shell:
        "bouncelab extract {params.run_dir:q} -o {output.flights:q} > {log:q} 2>&1"


rule calibrate:
    input:
        run_files,
        f"{RES}/runs/{{run}}/check.json",
    output:
        f"{RES}/runs/{{run}}/calibration.json",
    log:
        f"{RES}/logs/calibrate/{{run}}.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        run_dir=lambda wc: str(RAW / wc.run),
    shell:
        "bouncelab calibrate {params.run_dir:q} -o {output:q} > {log:q} 2>&1"
