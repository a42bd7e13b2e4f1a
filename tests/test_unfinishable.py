"""A configuration no trial can finish under is refused before a trial starts, through every
door, with the reason; a budget spent before the method starts still gives a failed row."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import SMALL_PATTERN, assert_clean_error, cli
from mcp import ClientSession
from test_mcp import call, run

from actionreasoning.errors import ConfigError
from actionreasoning.gym_env.env import BrickStackEnv
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.physics import PAPER
from actionreasoning.world.scene_spec import SceneSpec

REFUSED = "a trial takes at least 2.5 s"


def physics_file(tmp_path: Path, time_step_s: float) -> Path:
    """The paper profile at another time step, as a YAML file."""
    path = tmp_path / f"dt_{time_step_s:g}.yaml"
    profile = PAPER.model_copy(update={"name": "tiny", "time_step_s": time_step_s})
    path.write_text(yaml.safe_dump(profile.model_dump()))
    return path


def test_a_step_budget_that_cannot_hold_a_trial_is_refused_with_its_sums() -> None:
    with pytest.raises(ConfigError) as refused:
        TrialConfig(physics=PAPER.model_copy(update={"time_step_s": 1e-9}))
    message = str(refused.value)
    assert "400000 steps (--max-steps) of 1e-09 s (time_step_s) simulate 0.0004 s" in message
    assert REFUSED in message
    with pytest.raises(ConfigError, match=REFUSED):  # 599 steps of 1/240 s: 2.496 s
        TrialConfig(budget=TrialBudget(max_steps=599))
    assert TrialConfig(budget=TrialBudget(max_steps=600)).budget.max_steps == 600


def test_eval_refuses_a_one_nanosecond_time_step_in_one_line(
    tmp_path: Path, small_pattern: Path
) -> None:
    tiny = physics_file(tmp_path, 1e-9)
    out = tmp_path / "run"
    args = ["eval", "--method", "classical", "--pattern", str(small_pattern)]
    result = cli(*args, "--physics", str(tiny), "--out", str(out))
    assert_clean_error(result, "time_step_s", REFUSED)
    assert not (out / "results.jsonl").exists()


def test_the_gym_env_and_mcp_refuse_it_with_the_reason(tmp_path: Path) -> None:
    tiny = physics_file(tmp_path, 1e-9)
    with pytest.raises(ConfigError, match=REFUSED):
        BrickStackEnv(physics=str(tiny))

    async def scenario(client: ClientSession) -> None:
        data, refused = await call(client, "start_trial", physics=str(tiny))
        assert refused and data["refusal"]["code"] == "invalid_action"
        assert REFUSED in data["refusal"]["detail"], data

    run(scenario, tmp_path)


@pytest.mark.parametrize("method", list(Method))
def test_a_wall_time_spent_in_the_spawn_settle_is_a_failed_row(
    tmp_path: Path, method: Method
) -> None:
    """At 1e-5 s a step the spawn settle takes 25,000 steps: the wall time (1 ns) runs out
    in it, before the method starts. It used to escape the trial and end the run."""
    path = tmp_path / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    config = TrialConfig(
        physics=PAPER.model_copy(update={"time_step_s": 1e-5}),
        budget=TrialBudget(max_wall_s=1e-9),
        llm=None if method is Method.CLASSICAL else TrialConfig().llm,
    )
    spec = TrialSpec(
        method=method, pattern_name="small", goal=load_pattern(str(path), SceneSpec()),
        run_seed=0, trial=0, config=config,
    )  # fmt: skip
    result = run_trial(spec).result
    assert not result.success and result.failure is not None
    assert result.failure.reason == "time_budget" and result.bricks_placed == 0
    assert result.sim_steps < 25_000  # stopped within the spawn settle


def test_eval_writes_that_failed_row_and_goes_on(tmp_path: Path, small_pattern: Path) -> None:
    slow = physics_file(tmp_path, 1e-5)
    out = tmp_path / "run"
    args = ["eval", "--method", "classical", "--pattern", str(small_pattern), "--trials", "2"]
    result = cli(*args, "--physics", str(slow), "--max-trial-s", "1e-9", "--out", str(out))
    assert result.returncode == 0, result.stderr
    rows: list[dict[str, Any]] = [
        json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()
    ]
    assert [(r["trial"], r["failure"]["reason"]) for r in rows] == [
        (0, "time_budget"),
        (1, "time_budget"),
    ]
