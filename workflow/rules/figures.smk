# Stage 4: figures, one rule and one script each (showyourwork style). Every figure is a
# PNG plus a JSON of the numbers it shows, which the tests check against references.
# Captions (what the seed showed, what this figure shows) sit in workflow/report/.


rule fig01_takeoff_line:
    output:
        **figure_output("fig01_takeoff_line", "Model", run=False),
    log:
        f"{RES}/logs/figures/fig01_takeoff_line.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig01_takeoff_line.py"


rule fig02_bifurcation_ideal:
    input:
        f"{RES}/models/bifurcation_ideal.parquet",
    output:
        **figure_output("fig02_bifurcation_ideal", "Model", run=False),
    log:
        f"{RES}/logs/figures/fig02_bifurcation_ideal.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        grid=config["figures"]["bifurcation_gamma"],
        dpi=DPI,
    script:
        "../scripts/fig02_bifurcation_ideal.py"


rule fig03_rig:
    input:
        check=f"{RES}/runs/{{run}}/check.json",
    output:
        **figure_output("fig03_rig", "Rig and runs"),
    log:
        f"{RES}/logs/figures/{{run}}/fig03_rig.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        run_dir=lambda wc: str(RAW / wc.run),
        dpi=DPI,
    script:
        "../scripts/fig03_rig.py"


rule fig04_accelerometer:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
    output:
        **figure_output("fig04_accelerometer", "Measurement"),
    log:
        f"{RES}/logs/figures/{{run}}/fig04_accelerometer.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        run_dir=lambda wc: str(RAW / wc.run),
        dpi=DPI,
    script:
        "../scripts/fig04_accelerometer.py"


rule fig05_continuity:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
    output:
        **figure_output("fig05_continuity", "Measurement"),
    log:
        f"{RES}/logs/figures/{{run}}/fig05_continuity.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        run_dir=lambda wc: str(RAW / wc.run),
        dpi=DPI,
    script:
        "../scripts/fig05_continuity.py"


rule fig06_drop_test:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        calibration=f"{RES}/runs/{{run}}/calibration.json",
    output:
        **figure_output("fig06_drop_test", "Measurement"),
    log:
        f"{RES}/logs/figures/{{run}}/fig06_drop_test.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        run_dir=lambda wc: str(RAW / wc.run),
        dpi=DPI,
    script:
        "../scripts/fig06_drop_test.py"


rule fig07_bifurcation:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        model=f"{RES}/runs/{{run}}/sim/ideal.parquet",
    output:
        **figure_output("fig07_bifurcation", "Data and models"),
    log:
        f"{RES}/logs/figures/{{run}}/fig07_bifurcation.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig07_bifurcation.py"


rule fig08_return_maps:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
    output:
        **figure_output("fig08_return_maps", "Data and models"),
    log:
        f"{RES}/logs/figures/{{run}}/fig08_return_maps.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        gammas=config["figures"]["return_map_gammas"],
        dpi=DPI,
    script:
        "../scripts/fig08_return_maps.py"


rule fig09_friction:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        ideal=f"{RES}/runs/{{run}}/sim/ideal.parquet",
        friction=f"{RES}/runs/{{run}}/sim/friction.parquet",
    output:
        **figure_output("fig09_friction", "Data and models"),
    log:
        f"{RES}/logs/figures/{{run}}/fig09_friction.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig09_friction.py"


rule fig10_harmonic:
    input:
        flights=f"{RES}/runs/{{run}}/flights.parquet",
        harmonic=f"{RES}/runs/{{run}}/sim/harmonic.parquet",
    output:
        **figure_output("fig10_harmonic", "Data and models"),
    log:
        f"{RES}/logs/figures/{{run}}/fig10_harmonic.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig10_harmonic.py"


rule gap_over_gamma:
    input:
        f"{RES}/runs/{{run}}/compare.parquet",
    output:
        **figure_output("gap_over_gamma", "Gap over Gamma"),
    log:
        f"{RES}/logs/figures/{{run}}/gap_over_gamma.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig_gap_over_gamma.py"


rule energy_budget:
    input:
        f"{RES}/runs/{{run}}/energy.parquet",
    output:
        **figure_output("energy_budget", "Energy"),
    log:
        f"{RES}/logs/figures/{{run}}/energy_budget.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig_energy_budget.py"


rule fig_gap_diagnosis:
    input:
        f"{RES}/runs/{{run}}/diagnosis.json",
    output:
        **figure_output("fig_gap_diagnosis", "Gap diagnosis"),
    log:
        f"{RES}/logs/figures/{{run}}/fig_gap_diagnosis.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig_gap_diagnosis.py"


rule fig_blind_validation:
    input:
        f"{RES}/blind/scores.json",
    output:
        **figure_output("fig_blind_validation", "Gap diagnosis", run=False),
    log:
        f"{RES}/logs/figures/fig_blind_validation.log",
    conda:
        "../envs/bouncelab.yaml"
    params:
        dpi=DPI,
    script:
        "../scripts/fig_blind_validation.py"
