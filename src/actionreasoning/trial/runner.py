"""One trial: build a scene from the trial's seed, run a method, measure the result."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from actionreasoning.agents.calls import BuildResult, CallHook, failure_of
from actionreasoning.agents.catches import premove_refusals
from actionreasoning.agents.orchestrator import Orchestrator
from actionreasoning.agents.reasoner import Reasoner
from actionreasoning.agents.transcript import AgentCall, Outcome
from actionreasoning.agents.verification import Verification
from actionreasoning.agents.world import World
from actionreasoning.control.classical import run_classical
from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.errors import ConfigError, TrialAborted, UnreachableError
from actionreasoning.reasoners.factory import make_reasoner
from actionreasoning.reasoners.imperfect import ImperfectReasoner
from actionreasoning.records import FailureCode
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.perceive import Sensor
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import FINAL_SETTLE_S, SPAWN_SETTLE_S, TrialConfig
from actionreasoning.trial.metrics import placement_of
from actionreasoning.trial.results import (
    AnswerErrorCounts,
    BrickResult,
    Failure,
    FirstAttempts,
    LLMUsage,
    PerceptionErrors,
    PlacementMetrics,
    TrialResult,
    refusals_of,
)
from actionreasoning.trial.rules import (
    Method,
    check_observation,
    check_rung,
    rung_of,
    trial_seed,
)
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.geometry import QuatXYZW, Vec3
from actionreasoning.world.models import READY_POSE, GoalPattern
from actionreasoning.world.noise import vary_bricks
from actionreasoning.world.stages import StageEvent
from actionreasoning.world.success import SuccessRule
from actionreasoning.world.supply import lay_out


@dataclass(frozen=True)
class TrialSpec:
    """Everything that defines one trial: the run's configuration, the method, the goal,
    the run seed and the trial's index."""

    method: Method
    pattern_name: str
    goal: GoalPattern
    run_seed: int
    trial: int
    config: TrialConfig = TrialConfig()

    def __post_init__(self) -> None:
        if self.method is not Method.CLASSICAL and self.config.llm is None:
            raise ConfigError(f"--method {self.method} needs a reasoning backend (config.llm)")
        if self.method is Method.CLASSICAL and self.config.answer_errors.rate > 0:
            raise ConfigError("--method classical asks no reasoner; drop --answer-errors")
        check_rung(self.method, self.config.verify)
        check_observation(self.method, self.config.observe)

    @property
    def rung(self) -> Verification | None:
        """The rung of verification the trial runs under (None: the classical script)."""
        return rung_of(self.method, self.config.verify)


class TrialObserver:
    """Watches a trial as it runs, reading only: the scene every ``every_s`` of simulated
    time (and once before the first step), once the method is about to start, each
    finished stage, and each agent call as its record grows (answer, gate verdicts,
    outcome). Subclasses override what they watch."""

    #: Simulated seconds between two ``tick`` calls; None: no ticks.
    every_s: float | None = None

    def start(self, scene: Scene) -> None:
        """The scene after the spawn settle, before the method's first move."""

    def tick(self, scene: Scene) -> None:
        """The scene, every ``every_s`` simulated seconds."""

    def stage(self, scene: Scene, event: StageEvent) -> None:
        """A stage just finished (``event.brick`` -1: the trial's final settle)."""

    def call(self, scene: Scene, call: AgentCall) -> None:
        """An agent call's record, each time it grows."""


@dataclass(frozen=True)
class TrialWorld:
    """A trial's scene (after the spawn settle), the arm model, the controller driving it,
    the seed and the sensor."""

    scene: Scene
    arm: KinematicArm
    controller: WaypointController
    seed: int
    sensor: Sensor


@contextmanager
def trial_world(
    spec: TrialSpec, observers: Sequence[TrialObserver] = (), *, settle: bool = True
) -> Iterator[TrialWorld]:
    """The trial's world under its physics profile and perturbations, closed on exit: one
    brick of the goal's size per target, its mass scaled from the catalogue brick's. The
    ``observers`` tick from the spawn settle on; without ``settle`` the caller settles it
    (``SPAWN_SETTLE_S``)."""
    config, seed = spec.config, trial_seed(spec.run_seed, spec.trial)
    friction = config.physics.brick_lateral_friction
    sizes = [target.size_m for target in spec.goal.targets]
    nominals = [config.scene.brick_body(friction, size) for size in sizes]
    bodies = vary_bricks(config.noise.variation, nominals, seed)
    supply = lay_out(
        spec.goal.supply,
        sizes,
        [body.size_m[2] for body in bodies],
        config.scene,
        np.random.default_rng(seed),
    )
    with ExitStack() as cleanup:
        arm = KinematicArm()
        cleanup.callback(arm.close)
        ready = arm.solve(READY_POSE.position_m, READY_POSE.quat_xyzw).joints_rad
        scene = Scene(
            config.scene,
            supply.poses,
            ready,
            config.physics,
            config.budget,
            bodies,
            nominals,
            queue=supply.queue,
        )
        cleanup.callback(scene.close)
        for observer in observers:
            if observer.every_s is not None:
                scene.watch(scene.ticks_for(observer.every_s), observer.tick)
                observer.tick(scene)
        if settle:
            scene.step(scene.ticks_for(SPAWN_SETTLE_S))
        yield TrialWorld(
            scene=scene,
            arm=arm,
            controller=WaypointController(scene, arm, config.controller, config.safety),
            seed=seed,
            sensor=Sensor(scene, config.noise, seed),
        )


@dataclass(frozen=True)
class TrialRun:
    """A trial's result and the transcript of its agent calls (empty for classical)."""

    result: TrialResult
    transcript: tuple[AgentCall, ...]


def run_trial(
    spec: TrialSpec, observers: Sequence[TrialObserver] = (), reasoner: Reasoner | None = None
) -> TrialRun:
    """Run one trial start to finish, watched by ``observers``; failures become a
    ``failure`` record, never a crash. ``reasoner`` answers the agents in place of the
    backend ``spec.config.llm`` names (an outside agent: ``session.py``); results name it."""
    if reasoner is not None and spec.method is Method.CLASSICAL:
        raise ConfigError("--method classical asks no reasoner")
    with trial_world(spec, observers, settle=False) as world:
        scene, seed, controller = world.scene, world.seed, world.controller

        def stage(brick: int, name: str) -> None:
            event = StageEvent(brick=brick, stage=name)
            for observer in observers:
                observer.stage(scene, event)

        def on_call(call: AgentCall) -> None:
            for observer in observers:
                observer.call(scene, call)

        try:  # a budget spent already: the trial fails before its method starts
            scene.step(scene.ticks_for(SPAWN_SETTLE_S))
        except TrialAborted as error:
            outcome = BuildResult(failure=failure_of(error, None))
        else:
            for observer in observers:
                observer.start(scene)
            if spec.method is Method.CLASSICAL:
                outcome = _run_classical(controller, world.sensor, spec.goal, stage)
            else:
                agents_world = SimWorld(controller, spec.goal, world.sensor)
                outcome = run_agents(agents_world, spec, stage, on_call, reasoner, scene.deadline)
        try:
            scene.step(scene.ticks_for(FINAL_SETTLE_S))
            scene.check_physics()
        except TrialAborted as error:
            outcome.failure = outcome.failure or failure_of(error, None)
        stage(-1, "final")
        llm = None if reasoner is None else reasoner.name
        return TrialRun(measure(spec, seed, scene, outcome, llm), tuple(outcome.transcript))


def _run_classical(
    controller: WaypointController,
    sensor: Sensor,
    goal: GoalPattern,
    stage: Callable[[int, str], None],
) -> BuildResult:
    failure = None
    try:
        run_classical(controller, sensor, goal, lambda event: stage(event.brick, event.stage))
        controller.execute(Waypoint(pose=READY_POSE, gripper=GripperCommand.OPEN))
    except (UnreachableError, TrialAborted) as error:
        failure = failure_of(error, None)
    return BuildResult(placements={t.index: t.index for t in goal.targets}, failure=failure)


def run_agents(
    world: World,
    spec: TrialSpec,
    stage: Callable[[int, str], None],
    on_call: CallHook | None = None,
    reasoner: Reasoner | None = None,
    deadline: float | None = None,
) -> BuildResult:
    """The six gated agents, or the merged single agent, building ``spec``'s goal in
    ``world`` under the run's rung of verification with ``reasoner`` (default: the spec's
    backend, whose answers are given up at ``deadline``), its answers corrupted at the rate
    of ``config.answer_errors``."""
    config = spec.config
    assert config.llm is not None  # TrialSpec checks it
    if reasoner is None:
        reasoner = make_reasoner(config.llm, deadline)
    if config.answer_errors.rate > 0:
        seed = trial_seed(spec.run_seed, spec.trial)
        reasoner = ImperfectReasoner(reasoner, config.answer_errors, seed)
    runner = Orchestrator(
        world,
        reasoner,
        config.tolerances,
        config.retries,
        on_stage=stage,
        on_call=on_call,
        tier=config.tools,
        verify=spec.rung or Verification.FULL,
        single_agent=spec.method is Method.SINGLE_AGENT,
        observation=config.observe,
    )
    return runner.build(spec.goal)


class Bodies(Protocol):
    """What scoring reads of a trial's world at its end (a :class:`Scene` has it)."""

    @property
    def bricks(self) -> Sequence[object]: ...

    @property
    def ticks(self) -> int: ...

    def brick_pose(self, brick: int) -> tuple[Vec3, QuatXYZW]: ...

    def brick_velocity(self, brick: int) -> tuple[Vec3, Vec3]: ...


def measure(
    spec: TrialSpec, seed: int, scene: Bodies, outcome: BuildResult, llm: str | None
) -> TrialResult:
    """The trial's result line, from the bodies at the end of trial ``seed`` and the build's
    outcome; ``llm`` names the reasoner if not the spec's backend."""
    config, rule, failure = spec.config, spec.config.success_rule, outcome.failure
    if llm is None:
        llm = "none" if config.llm is None or spec.method is Method.CLASSICAL else config.llm.label
    unplaced = iter(sorted(set(range(len(scene.bricks))) - set(outcome.placements.values())))
    bricks = []
    for target in spec.goal.targets:
        # A target left unbuilt is scored against a brick that was not placed anywhere.
        brick = outcome.placements.get(target.index)
        brick = next(unplaced) if brick is None else brick
        position, quat = scene.brick_pose(brick)
        m = placement_of(position, quat, target)
        bricks.append(
            BrickResult(
                id=brick,
                size=target.size_m,
                target_position=target.pose.position_m,
                target_orientation=target.pose.quat_xyzw,
                final_position=position,
                final_orientation=quat,
                center_offset_cm=m.center_offset_cm,
                rotation_error_deg=m.rotation_error_deg,
                symmetric_rotation_error_deg=m.symmetric_rotation_error_deg,
                iou=m.iou,
                llm_usage=_usage_of(outcome.transcript, brick),
            )
        )
    within = [rule.is_placed(b) for b in bricks]
    moving = [b.id for b in bricks if not rule.is_at_rest(*scene.brick_velocity(b.id))]
    if failure is None and not all(within):
        failure = misplaced(bricks, rule)
    if failure is None and moving:
        failure = Failure(reason=FailureCode.NOT_AT_REST, detail=f"bricks still moving: {moving}")
    return TrialResult(
        method=str(spec.method),
        pattern=spec.pattern_name,
        physics=config.physics.name,
        noise=config.noise.name,
        tools=config.tools,
        observe=config.observe,
        verify=spec.rung,
        seed=spec.run_seed,
        trial=spec.trial,
        trial_seed=seed,
        success=failure is None,
        llm=llm,
        bricks=tuple(bricks),
        bricks_placed=sum(within),
        metrics=PlacementMetrics(
            center_offset_cm=float(np.mean([b.center_offset_cm for b in bricks])),
            rotation_error_deg=float(np.mean([b.rotation_error_deg for b in bricks])),
            symmetric_rotation_error_deg=float(
                np.mean([b.symmetric_rotation_error_deg for b in bricks])
            ),
            iou=float(np.mean([b.iou for b in bricks])),
        ),
        failure=failure,
        llm_usage=outcome.usage,
        llm_usage_by_agent={
            agent: _usage_of(outcome.transcript, agent=agent)
            for agent in dict.fromkeys(call.agent for call in outcome.transcript)
        },
        decisions=outcome.decisions,
        fallback_decisions=outcome.fallbacks,
        answer_errors=AnswerErrorCounts.of(
            outcome.transcript,
            failure,
            {b.id for b, ok in zip(bricks, within, strict=True) if not ok},
        )
        if config.answer_errors.rate
        else None,
        refusals=refusals_of(outcome.transcript),
        first_attempts=first_attempts_of(outcome.transcript),
        perception=perception_of(outcome.transcript),
        premove_refusals=premove_refusals(outcome.transcript),
        sim_steps=scene.ticks,
    )


def _usage_of(
    transcript: Sequence[AgentCall], brick: int | None = None, agent: str | None = None
) -> LLMUsage:
    """LLM usage summed over the calls about ``brick`` or of ``agent``."""
    return sum(
        (
            call.usage
            for call in transcript
            if (brick is None or call.brick_in_hand == brick)
            and (agent is None or call.agent == agent)
        ),
        LLMUsage(),
    )


def first_attempts_of(transcript: Sequence[AgentCall]) -> dict[str, FirstAttempts]:
    """Each agent's calls of attempt 1 and how many were accepted or executed as they came,
    the agents in the order they were first asked."""
    counts: dict[str, FirstAttempts] = {}
    for call in transcript:
        if call.attempt == 1:
            accepted = call.outcome in (Outcome.ACCEPTED, Outcome.EXECUTED)
            counts[call.agent] = counts.get(call.agent, FirstAttempts()) + FirstAttempts(
                asked=1, accepted=int(accepted)
            )
    return counts


def perception_of(transcript: Sequence[AgentCall]) -> dict[str, PerceptionErrors]:
    """Each agent's perception errors, over its answers that named a brick's pose."""
    errors: dict[str, PerceptionErrors] = {}
    for call in transcript:
        if call.perceived is not None:
            seen = call.perceived
            errors[call.agent] = errors.get(call.agent, PerceptionErrors()) + PerceptionErrors(
                answers=1,
                centre_offset_cm_sum=seen.centre_offset_cm,
                centre_offset_cm_max=seen.centre_offset_cm,
                yaw_error_deg_sum=seen.yaw_error_deg,
                yaw_error_deg_max=seen.yaw_error_deg,
            )
    return errors


def misplaced(bricks: Sequence[BrickResult], rule: SuccessRule) -> Failure:
    """The failure of a finished build with bricks outside the success rule, naming the one
    furthest past its limits (in units of the limits: offset and rotation alike)."""
    outside = [b for b in bricks if not rule.is_placed(b)]
    worst = max(bricks, key=rule.excess)
    return Failure(
        reason=FailureCode.MISPLACED,
        detail=f"{len(outside)} of {len(bricks)} bricks outside "
        f"{rule.max_center_offset_cm} cm / {rule.max_rotation_error_deg} deg; worst brick "
        f"{worst.id}: {worst.center_offset_cm:.2f} cm, {worst.rotation_error_deg:.2f} deg",
    )
