"""A small shear cell for the tests: the default schema section with fewer disks and
shorter times (docs/shear.md)."""

import pytest
import yaml

from granpipe.config import fill_defaults, schema_dir


def shear_section(**overrides) -> dict:
    """The schema's default ``shear`` section, each ``overrides[section]`` merged in."""
    schema = yaml.safe_load((schema_dir() / "shear.schema.yaml").read_text())
    cfg: dict = {}
    fill_defaults(cfg, schema, schema)
    for key, value in overrides.items():
        cfg[key] = {**cfg[key], **value}
    return cfg


@pytest.fixture
def tiny():
    """Inner ring of 12, outer of 30 wall disks (about 60 disks at phi = 0.82), short times."""
    return shear_section(
        physics={"phi": 0.82, "n_inner": 12, "n_outer": 30},
        preparation={"growth_stages": 10, "growth_s": 0.4, "steady_s": 0.4},
        protocol={"record_s": 0.4, "tangent_alignment_s": 0.1, "sample_s": 0.02},
        ensemble={"n_replicas": 2, "batch_size": 1},
        fits={"aligned_before_s": 0.1, "aligned_after_s": 0.1},
    )
