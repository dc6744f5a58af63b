# bouncelab: raw continuity recordings -> flights -> calibration -> models -> gap -> report.
#
#   snakemake --cores 2            everything under results/ (profiles/default is picked up)
#   snakemake --report report.zip  Snakemake's own report of the outputs marked report()
#
# Runs are discovered from raw/*/run.yaml: a new folder gives new jobs and a new report
# section with no edit here. Stages live in workflow/rules/, one file each.

from snakemake.utils import min_version, validate

min_version("8.10")


configfile: "config/config.yaml"


validate(config, "workflow/schemas/config.schema.yaml")


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/runs.smk"
include: "workflow/rules/models.smk"
include: "workflow/rules/compare.smk"
include: "workflow/rules/diagnose.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/report.smk"


rule all:
    default_target: True
    input:
        all_run_targets,
        f"{RES}/report/report.html",
        f"{RES}/report/report.pdf",
