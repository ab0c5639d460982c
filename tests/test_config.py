"""Config validation: defaults filled from the schema, bad keys named in one line."""

from pathlib import Path

import pytest
import yaml

from oneocean.config import load_config, load_schema, validate_config
from oneocean.errors import ConfigError
from workflow_helpers import REPO

DEFAULT = REPO / "config" / "config.yaml"


def test_default_config_is_valid_and_every_key_documented():
    cfg = load_config(DEFAULT)
    assert cfg["sources"]["currents"] == "synthetic"
    schema = load_schema()

    def walk(node, path):
        props = node.get("properties", {})
        for key, sub in props.items():
            assert "description" in sub, f"{path}{key} has no description"
            assert "default" in sub, f"{path}{key} has no default"
            walk(sub, f"{path}{key}.")

    walk(schema, "")
    # every key in the shipped config file carries a comment line above or beside it
    text = DEFAULT.read_text().splitlines()
    for i, line in enumerate(text):
        stripped = line.strip()
        if stripped and not stripped.startswith("#") and stripped.endswith(":"):
            before = text[i - 1].strip()
            assert before.startswith("#") or "#" in line or text[i - 1].strip().endswith(":"), \
                f"config key without a comment: {stripped}"


def test_defaults_are_filled_from_schema():
    cfg = validate_config({})
    assert cfg["region"]["name"] == "synthetic_coast"
    assert cfg["variants"]["tiny"]["resolution_deg"] > 0
    assert cfg["cmems"]["dataset_id"] == "cmems_mod_glo_phy-cur_anfc_0.083deg_P1D-m"


@pytest.mark.parametrize(
    "override, named",
    [
        ({"regoin": {}}, "regoin"),
        ({"region": {"bbox": {"wset": 1.0}}}, "region.bbox.wset"),
        ({"region": {"bbox": {"west": "x"}}}, "region.bbox.west"),
        ({"variants": {"tiny": {"extent_fraction": 2.0}}}, "variants.tiny.extent_fraction"),
        ({"sources": {"currents": "cmem"}}, "sources.currents"),
        ({"region": {"bbox": {"west": 3.0, "east": 2.0}}}, "region.bbox"),
        ({"region": {"time": {"start": "2025-02-01T00:00:00"}}}, "region.time"),
        ({"sources": {"bathymetry": "etopo"}}, "etopo.path"),
        ({"synthetic": {"depths_m": []}}, "synthetic.depths_m"),
    ],
)
def test_bad_key_is_named_in_one_line(override, named):
    with pytest.raises(ConfigError) as exc:
        load_config(DEFAULT, overrides=override)
    msg = str(exc.value)
    assert named in msg
    assert "\n" not in msg


def test_unreadable_config_file_is_named(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("region: [unclosed\n")
    with pytest.raises(ConfigError, match="bad.yaml"):
        load_config(bad)
    with pytest.raises(ConfigError, match="missing.yaml: not found"):
        load_config(tmp_path / "missing.yaml")


def test_region_files_are_valid():
    for region in sorted((REPO / "config" / "regions").glob("*.yaml")):
        cfg = load_config(DEFAULT, region)
        assert cfg["region"]["name"] == yaml.safe_load(region.read_text())["region"]["name"]


def test_schema_is_package_data_with_registry_enums():
    import oneocean
    from oneocean import registry
    from oneocean.config import SCHEMA_PATH

    assert SCHEMA_PATH.is_file()
    assert SCHEMA_PATH.parent == Path(oneocean.__file__).parent / "data"
    assert not (REPO / "workflow" / "schemas").exists()
    rollouts = load_schema()["properties"]["rollouts"]["properties"]
    assert rollouts["tasks"]["items"]["enum"] == list(registry.task_ids())
    assert rollouts["tasks"]["default"] == list(registry.builtin_task_ids())
    assert rollouts["methods"]["items"]["enum"] == list(registry.method_names())
    # the file itself lists no task or method: the registry is the one list
    assert "G2G" not in SCHEMA_PATH.read_text() and "oracle]" not in SCHEMA_PATH.read_text()
    assert validate_config({})["plugins"] == []
    with pytest.raises(ConfigError, match=r"rollouts\.tasks\.1.*'XX'"):
        validate_config({"rollouts": {"tasks": ["G2G", "XX"]}})
