"""Command-line overrides whose nested values arrive as strings
(``snakemake --config 'rollouts={"episodes": 5}'`` gives ``"5"``) validate as the numbers,
booleans and nulls the schema asks for; values that are no such thing stay one-line errors."""

import subprocess
import sys

import pytest
import yaml

from oneocean.config import coerce_strings, load_config, validate_config, validate_data_config
from oneocean.errors import ConfigError
from workflow_helpers import REPO

DEFAULT = REPO / "config" / "config.yaml"


def _snakemake_like(text: str):
    """What ``snakemake --config key=<text>`` makes of a nested value (YAML BaseLoader:
    every scalar a string)."""
    return yaml.load(text, Loader=yaml.loader.BaseLoader)


def test_nested_strings_become_the_schema_types():
    overrides = {
        "rollouts": _snakemake_like('{"episodes": 5, "seed": 1001, "tiers": [1, 3], '
                                    '"current_gain": 0.5, "tide": {"amplitude_ms": 0.3, '
                                    '"period_s": 44712}, "replicate": {"seeds": [7, 8]}}'),
        "sources": _snakemake_like('{"tides": false}'),
        "region": _snakemake_like('{"bbox": {"west": -4.5, "east": -4.3, "south": 50.1, '
                                  '"north": 50.4}, "max_depth_m": 80}'),
        "variants": _snakemake_like('{"tiny": {"extent_fraction": 0.5, "resolution_deg": '
                                    '4e-3, "hours": 6, "max_depth_m": 20.0}}'),
        "rl": _snakemake_like('{"enabled": no, "episodes": null, "seeds": [3]}'),
    }
    assert overrides["rollouts"]["episodes"] == "5"   # the problem: strings
    cfg = load_config(DEFAULT, overrides=overrides)
    ro = cfg["rollouts"]
    assert ro["episodes"] == 5 and type(ro["episodes"]) is int
    assert ro["seed"] == 1001 and ro["tiers"] == [1, 3]
    assert ro["current_gain"] == 0.5 and type(ro["current_gain"]) is float
    assert ro["tide"] == {"amplitude_ms": 0.3, "period_s": 44712, "phase_rad": 0.0}
    assert ro["replicate"]["seeds"] == [7, 8]
    assert cfg["sources"]["tides"] is False
    assert cfg["region"]["bbox"]["west"] == -4.5 and cfg["region"]["max_depth_m"] == 80
    assert type(cfg["region"]["max_depth_m"]) is int   # as YAML would have read `80`
    assert cfg["variants"]["tiny"]["resolution_deg"] == 0.004
    assert cfg["rl"]["enabled"] is False and cfg["rl"]["episodes"] is None
    assert cfg["rl"]["seeds"] == [3]


def test_coerced_config_hashes_like_the_yaml_one():
    from oneocean.io import config_hash

    from_yaml = load_config(DEFAULT, overrides=yaml.safe_load(
        "rollouts: {episodes: 5, current_gain: 0.5, tiers: [1, 3]}"))
    from_cli = load_config(DEFAULT, overrides={"rollouts": _snakemake_like(
        '{"episodes": 5, "current_gain": 0.5, "tiers": [1, 3]}')})
    assert config_hash(from_cli) == config_hash(from_yaml)


@pytest.mark.parametrize("override, named", [
    ({"rollouts": {"episodes": "five"}}, "key 'rollouts.episodes': 'five' is not of type "
                                         "'integer'"),
    ({"rollouts": {"episodes": "2.5"}}, "key 'rollouts.episodes': '2.5' is not of type "
                                        "'integer'"),
    ({"rollouts": {"episodes": "0"}}, "key 'rollouts.episodes': 0 is less than the minimum"),
    ({"rollouts": {"tiers": ["4"]}}, "key 'rollouts.tiers.0': '4' is not one of [1, 2, 3]"),
    ({"sources": {"tides": "maybe"}}, "key 'sources.tides': 'maybe' is not of type 'boolean'"),
    ({"rollouts": {"current_gain": "nan"}}, "key 'rollouts.current_gain': 'nan' is not of "
                                            "type 'number'"),
])
def test_bad_strings_are_still_one_line_errors(override, named):
    with pytest.raises(ConfigError) as err:
        load_config(DEFAULT, overrides=override)
    assert named in str(err.value) and "\n" not in str(err.value)


def test_strings_the_schema_wants_stay_strings():
    cfg = validate_config({"region": {"name": "123"}, "cmems": {"dataset_version": "null",
                                                                "retries": "4"}})
    assert cfg["region"]["name"] == "123"               # type: string
    assert cfg["cmems"]["dataset_version"] == "null"    # type: [string, null]: a string is fine
    assert cfg["cmems"]["retries"] == 4
    assert validate_data_config({"synthetic": {"seed": "7", "depths_m": ["0.5", "10"]}}
                                )["synthetic"] == {**validate_data_config({})["synthetic"],
                                                   "seed": 7, "depths_m": [0.5, 10]}


def test_coerce_strings_unit():
    schema = {"type": "object", "$defs": {"n": {"type": "number"}}, "properties": {
        "a": {"type": "integer"}, "b": {"$ref": "#/$defs/n"}, "c": {"type": ["integer", "null"]},
        "d": {"oneOf": [{"type": "null"}, {"type": "object",
                                           "properties": {"x": {"type": "boolean"}}}]},
        "e": {"type": "array", "items": {"enum": [1, 2, 3]}},
        "f": {"type": "object", "additionalProperties": {"type": "number"}},
        "g": {"type": "boolean"}}}
    cfg = {"a": "+3", "b": "1e3", "c": "~", "d": {"x": "True"}, "e": ["2", "x"],
           "f": {"k": "-1.5"}, "g": "0"}
    out = coerce_strings(cfg, schema)
    assert out is cfg
    assert cfg == {"a": 3, "b": 1000.0, "c": None, "d": {"x": True}, "e": [2, "x"],
                   "f": {"k": -1.5}, "g": "0"}
    assert coerce_strings({"d": "null"}, schema) == {"d": None}
    assert coerce_strings("7", {"type": "integer"}) == 7
    assert type(coerce_strings("5.0", {"type": "integer"})) is int
    assert coerce_strings("1.5", {"type": "integer"}) == "1.5"     # left for validation
    assert coerce_strings("yes", {"type": ["boolean", "null"]}) is True
    assert coerce_strings("7", {"type": ["string", "integer"]}) == "7"


def test_snakemake_dry_run_accepts_numeric_override(tmp_path):
    cmd = [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile"),
           "--directory", str(tmp_path), "--configfile", str(DEFAULT), "--cores", "1", "-n",
           "paper_tables", "--quiet", "all"]
    ok = subprocess.run(cmd + ["--config", 'rollouts={"episodes": 5, "tiers": [1, 3]}'],
                        capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0, ok.stderr[-2000:]
    bad = subprocess.run(cmd + ["--config", 'rollouts={"episodes": "five"}'],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode != 0
    assert "config key 'rollouts.episodes': 'five' is not of type 'integer'" in (
        bad.stdout + bad.stderr)
