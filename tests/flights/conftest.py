"""Fixtures: short virtual-rig recordings written into tmp folders (bouncelab.rig)."""

import pytest
import yaml


@pytest.fixture(scope="session")
def make_rig(tmp_path_factory):
    """make_rig(name, config_dict) -> (run_dir, truth_path); cached per name."""
    from bouncelab.rig import run_rig

    root = tmp_path_factory.mktemp("rig")
    cache = {}

    def make(name, cfg):
        if name not in cache:
            cfg_path = root / f"{name}.yaml"
            cfg_path.write_text(yaml.safe_dump(cfg))
            run_dir, truth = root / "raw" / name, root / f"{name}_truth.parquet"
            run_rig(cfg_path, run_dir, truth)
            cache[name] = (run_dir, truth)
        return cache[name]

    return make
