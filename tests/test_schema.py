"""The JSON Schemas of a run's records (`actionreasoning schema`) declare their dialect
(draft 2020-12) and the bounds of their values, and a validator holds real records to them:
what a run writes passes, an IoU of 1.5 or a negative count does not. Every number of the
trial configuration's schema has a bound."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from conftest import SMALL_PATTERN, cli
from jsonschema import Draft202012Validator
from jsonschema.exceptions import best_match
from pydantic import BaseModel, ValidationError
from test_courses import brick
from test_run_dir import result

from actionreasoning.errors import ConfigError
from actionreasoning.records import LLMUsage
from actionreasoning.runs.run_dir import RunManifest
from actionreasoning.runs.summary import RunSummary, summarize
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.metrics import box_iou
from actionreasoning.trial.results import JSON_SCHEMA_DIALECT, TrialResult, json_schema
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import MAX_COORDINATE_M

MODELS: tuple[type[BaseModel], ...] = (TrialResult, RunSummary, TrialConfig)
BOUNDS = ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum")


def line() -> dict[str, Any]:
    """A results line with two bricks and a model's usage, as JSON."""
    usage = LLMUsage(calls=3, prompt_tokens=900, completion_tokens=40, latency_s=2.5)
    made = result(0, success=False).model_copy(
        update={"bricks": (brick(0.03, 0.4), brick(0.09, 2.5)), "llm_usage": usage}
    )
    return json.loads(made.model_dump_json())


def summary() -> dict[str, Any]:
    return json.loads(summarize([result(0), result(1, success=False)], 1.0).model_dump_json())


def config() -> dict[str, Any]:
    """The default trial configuration as run.json records it."""
    manifest = RunManifest.sealed("agents", "pyramid", "0" * 64, 0, TrialConfig())
    return json.loads(manifest.model_dump_json(indent=2))["config"]


def numbers(node: Any, path: str = "") -> Iterator[tuple[str, dict[str, Any]]]:
    """Every number and integer of a schema, with its path in the schema."""
    if isinstance(node, dict):
        if node.get("type") in ("number", "integer"):
            yield path, node
        for key, value in node.items():
            yield from numbers(value, f"{path}/{key}")
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from numbers(value, f"{path}/{index}")


@pytest.mark.parametrize("model", MODELS)
def test_each_schema_declares_draft_2020_12_and_is_valid_in_it(model: type[BaseModel]) -> None:
    schema = json_schema(model)
    assert schema["$schema"] == JSON_SCHEMA_DIALECT
    assert jsonschema.validators.validator_for(schema) is Draft202012Validator
    Draft202012Validator.check_schema(schema)


@pytest.mark.parametrize(
    ("model", "record", "change", "refused"),
    [
        (TrialResult, line, ("bricks", 0, "iou"), 1.5),
        (TrialResult, line, ("metrics", "iou"), -0.1),
        (TrialResult, line, ("bricks", 1, "center_offset_cm"), -0.5),
        (TrialResult, line, ("bricks", 1, "rotation_error_deg"), 180.5),
        (TrialResult, line, ("metrics", "symmetric_rotation_error_deg"), -1.0),
        (TrialResult, line, ("bricks_placed",), -1),
        (TrialResult, line, ("sim_steps",), -10),
        (TrialResult, line, ("llm_usage", "prompt_tokens"), -1),
        (TrialResult, line, ("llm_usage", "latency_s"), -0.5),
        (TrialResult, line, ("trial",), -1),
        (TrialResult, line, ("bricks", 0, "size", 2), 0.0),
        (TrialResult, line, ("bricks", 0, "target_position", 0), 150.0),
        (TrialResult, line, ("bricks", 0, "final_orientation", 3), 1.5),
        (TrialResult, line, ("schema_version",), 0),
        (RunSummary, summary, ("success_interval", "high"), 1.1),
        (RunSummary, summary, ("all_trials", "center_offset_cm", "mean"), -0.2),
        (RunSummary, summary, ("all_trials", "iou", "ci_low"), -0.1),
        (RunSummary, summary, ("success_rate",), 1.2),
        (RunSummary, summary, ("successes",), -1),
        (RunSummary, summary, ("trials",), 0),
        (RunSummary, summary, ("wall_time_s",), -1.0),
        (RunSummary, summary, ("all_trials", "iou", "std"), -0.1),
        (RunSummary, summary, ("courses",), [{"course": 0, "bricks": 1, "center_offset_cm":
         [0.1, 0.0], "rotation_error_deg": [0.1, 0.0], "iou": [1.5, 0.0]}]),
    ],
)  # fmt: skip
def test_a_value_out_of_its_bounds_fails_validation(
    model: type[BaseModel],
    record: Any,
    change: tuple[str | int, ...],
    refused: Any,
) -> None:
    validator = Draft202012Validator(json_schema(model))
    data = record()
    assert list(validator.iter_errors(data)) == []
    model.model_validate(data)
    *path, last = change
    target = data
    for key in path:
        target = target[key]
    target[last] = refused
    error = best_match(validator.iter_errors(data))  # into an anyOf: the branch that fails
    assert error is not None and list(error.absolute_path)[: len(change)] == list(change)
    if change != ("trial",):  # refused by the reader with its own message (runs/run_dir.py)
        with pytest.raises(ValidationError):
            model.model_validate(data)


def unbounded(model: type[BaseModel]) -> list[str]:
    """The paths of a schema's numbers that have neither a lower nor an upper bound."""
    return [path for path, node in numbers(json_schema(model)) if not set(BOUNDS) & node.keys()]


def test_every_number_of_the_schemas_has_a_bound_but_a_brick_s_final_position() -> None:
    """Where the physics left a brick is the one number without a bound: nothing keeps a
    thrown brick within one, and a bound its writer could break would fail a trial."""
    found = dict(numbers(json_schema(TrialConfig)))
    assert len(found) > 50  # the walk reaches into every part ($defs, prefixItems, anyOf)
    assert unbounded(TrialConfig) == []
    assert unbounded(RunSummary) == []
    final = "/$defs/BrickResult/properties/final_position/prefixItems/"
    assert unbounded(TrialResult) == [f"{final}{axis}" for axis in range(3)]
    workspace = found["/$defs/WorkspaceBox/properties/high_m/prefixItems/0"]
    assert (workspace["minimum"], workspace["maximum"]) == (-MAX_COORDINATE_M, MAX_COORDINATE_M)


def test_the_default_config_as_run_json_records_it_passes_its_schema() -> None:
    Draft202012Validator(json_schema(TrialConfig)).validate(config())


@pytest.mark.parametrize(
    ("change", "refused"),
    [
        (("budget", "max_wall_s"), -1.0),
        (("budget", "max_steps"), 0),
        (("llm", "sampling", "top_p"), 1.5),
        (("llm", "sampling", "temperature"), 2.5),
        (("llm", "sampling", "seed"), 2**32),
        (("llm", "limits", "repairs"), -1),
        (("retries", "placement_attempts"), 0),
        (("controller", "max_linear_speed_mps"), 0.0),
        (("safety", "max_tcp_speed_mps"), -2.5),
        (("success_rule", "max_rotation_error_deg"), 181.0),
        (("scene", "brick_size_m", 2), 0.0),
        (("scene", "pick_azimuth_deg", 0), -190.0),
        (("scene", "reach", "max_azimuth_deg"), 190.0),
        (("scene", "workspace", "high_m", 0), 150.0),
    ],
)
def test_a_config_value_out_of_its_bounds_fails_validation(
    change: tuple[str | int, ...], refused: Any
) -> None:
    """The schema refuses it, and so does the configuration read back (run.json): budgets
    and sampling settings with their own messages (ConfigError), the rest as pydantic's."""
    data = config()
    *path, last = change
    target = data
    for key in path:  # sampling settings at their defaults are left out of run.json
        target = target.setdefault(key, {}) if isinstance(target, dict) else target[key]
    target[last] = refused
    error = best_match(Draft202012Validator(json_schema(TrialConfig)).iter_errors(data))
    assert error is not None and list(error.absolute_path) == list(change)
    with pytest.raises((ValidationError, ConfigError)):
        TrialConfig.model_validate(data)


def test_coinciding_boxes_have_an_iou_of_one_not_more() -> None:
    """The hull's volume of two coinciding boxes exceeds theirs by rounding (up to 1e-14 in
    a third of these): the IoU is at most 1, as its schema says."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        quat = rng.normal(size=4)
        box = Box(tuple(rng.uniform(-1, 1, 3)), tuple(quat), tuple(rng.uniform(0.03, 0.3, 3)))
        assert box_iou(box, box) == pytest.approx(1.0, abs=1e-12)
        assert box_iou(box, box) <= 1.0


@pytest.mark.slow
def test_what_a_real_run_writes_passes_its_schemas(tmp_path: Path) -> None:
    pattern = tmp_path / "small.json"
    pattern.write_text(json.dumps(SMALL_PATTERN))
    out = tmp_path / "run"
    outcome = cli(
        "eval", "--method", "classical", "--pattern", str(pattern), "--trials", "2",
        "--physics", "precise", "--out", str(out),
    )  # fmt: skip
    assert outcome.returncode == 0, outcome.stderr
    records = [
        *((TrialResult, json.loads(text)) for text in (out / "results.jsonl").open()),
        (RunSummary, json.loads((out / "summary.json").read_text())),
        (TrialConfig, json.loads((out / "run.json").read_text())["config"]),
    ]
    for model, data in records:
        Draft202012Validator(json_schema(model)).validate(data)
