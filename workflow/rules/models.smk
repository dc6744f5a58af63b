# Stage 2: model variants, each simulated under a sweep run's own protocol (its steps,
# drive frequency and settle cycles, state carried over), and the model-only diagrams.


rule simulate:
    input:
        check=f"{RES}/runs/{{run}}/check.json",
        calibration=calibration_input,
    output:
        f"{RES}/runs/{{run}}/sim/{{variant}}.parquet",
    log:
        f"{RES}/logs/simulate/{{run}}/{{variant}}.log",
    benchmark:
        f"{RES}/benchmarks/simulate/{{run}}/{{variant}}.tsv"
    conda:
        "../envs/bouncelab.yaml"
    # one core: a job is mostly start-up and table building, so two jobs side by side
    # finish sooner than one job on two cores (numba's prange spreads what is left)
    threads: 1
    resources:
        mem_mb=2000,
    params:
        run_dir=lambda wc: str(RAW / wc.run),
        variant=lambda wc: config["variants"][wc.variant],
        defaults=config["calibration_defaults"],
        starts=config["simulation"]["starts"],
        seed=config["simulation"]["seed"],
    script:
        "../scripts/simulate_variant.py"


rule bifurcation_ideal:
    output:
        f"{RES}/models/bifurcation_ideal.parquet",
    log:
        f"{RES}/logs/bifurcation_ideal.log",
    benchmark:
        f"{RES}/benchmarks/bifurcation_ideal.tsv"
    conda:
        "../envs/bouncelab.yaml"
    threads: 2
    params:
        grid=config["figures"]["bifurcation_gamma"],
        flights=config["figures"]["bifurcation_flights"],
        skip=config["figures"]["bifurcation_skip"],
    shell:
        "bouncelab simulate --model ideal --gamma {params.grid[0]}:{params.grid[1]}:{params.grid[2]}"
        " --flights {params.flights} --skip {params.skip} -o {output:q} > {log:q} 2>&1"
