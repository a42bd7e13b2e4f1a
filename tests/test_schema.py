"""The JSON Schemas of a run's records (`actionreasoning schema`) declare their dialect
(draft 2020-12) and the bounds of their values, and a validator holds real records to them:
what a run writes passes, an IoU of 1.5 or a negative count does not."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from conftest import SMALL_PATTERN, cli
from jsonschema import Draft202012Validator
from pydantic import BaseModel, ValidationError
from test_courses import brick
from test_run_dir import result

from actionreasoning.records import LLMUsage
from actionreasoning.runs.summary import RunSummary, summarize
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.metrics import box_iou
from actionreasoning.trial.results import JSON_SCHEMA_DIALECT, TrialResult, json_schema
from actionreasoning.world.boxes import Box

MODELS: tuple[type[BaseModel], ...] = (TrialResult, RunSummary, TrialConfig)


def line() -> dict[str, Any]:
    """A results line with two bricks and a model's usage, as JSON."""
    usage = LLMUsage(calls=3, prompt_tokens=900, completion_tokens=40, latency_s=2.5)
    made = result(0, success=False).model_copy(
        update={"bricks": (brick(0.03, 0.4), brick(0.09, 2.5)), "llm_usage": usage}
    )
    return json.loads(made.model_dump_json())


def summary() -> dict[str, Any]:
    return json.loads(summarize([result(0), result(1, success=False)], 1.0).model_dump_json())


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
    errors = list(validator.iter_errors(data))
    assert errors and list(errors[0].absolute_path)[: len(change)] == list(change)
    if change != ("trial",):  # refused by the reader with its own message (runs/run_dir.py)
        with pytest.raises(ValidationError):
            model.model_validate(data)


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
