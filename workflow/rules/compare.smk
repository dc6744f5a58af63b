# Stage 3: data against each model variant (gap over Gamma) and energy budgets.


rule compare:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        sims=expand(f"{RES}/runs/{{{{run}}}}/sim/{{variant}}.parquet", variant=VARIANTS),
    output:
        report(
            f"{RES}/runs/{{run}}/compare.parquet",
            caption="../report/compare.rst",
            category="Gap over Gamma",
            subcategory="{run}",
        ),
    log:
        f"{RES}/logs/compare/{{run}}.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        variants=VARIANTS,
    script:
        "../scripts/compare_models.py"


rule energy:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        sims=expand(f"{RES}/runs/{{{{run}}}}/sim/{{variant}}.parquet", variant=VARIANTS),
    output:
        f"{RES}/runs/{{run}}/energy.parquet",
    log:
        f"{RES}/logs/energy/{{run}}.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        run_dir=lambda wc: str(RAW / wc.run),
        variants=VARIANTS,
    script:
        "../scripts/energy_budget.py"
