# granpipe workflow: four granular-dynamics studies (docs/), five stages each
# (docs/architecture.md).
#
#   snakemake --cores 2                                  # default scale (config/config.yaml)
#   snakemake --cores 2 --configfile config/quick.yaml   # another scale: that file alone
#   snakemake --profile workflow/profiles/slurm --configfile config/paper.yaml
#
# A scale file given with --configfile is used on its own (not merged over
# config/config.yaml), so each scale is exactly what its file says.

from granpipe.config import read_yaml, validate as validate_config

if not workflow.config_settings.configfiles:

    configfile: "config/config.yaml"


# Stops the workflow before any job runs, naming the bad key (granpipe.errors.ConfigError):
# the config files are read again strictly (a key given twice is refused with its line;
# Snakemake's own reader keeps the last), then validated as `granpipe check-config` does.
for _path in workflow.config_settings.configfiles or ["config/config.yaml"]:
    read_yaml(_path)
validate_config(config, f"{workflow.basedir}/workflow/schemas/config.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/drum.smk"
include: "workflow/rules/column.smk"
include: "workflow/rules/box.smk"
include: "workflow/rules/shear.smk"


rule all:
    input:
        all_targets(),
    default_target: True
