"""A trial's Rerun recording (``eval --rerun``), made in memory and returned as ``.rrd`` bytes.

On the ``sim`` timeline (simulated seconds), every SAMPLE_S and at each finished stage: the
bricks as boxes and their targets as ghost boxes, the gripper's pose and opening, the arm's
link frames; scalars for the pad forces, the held brick's slip (its speed relative to the
gripper) and each brick's centre offset from its target once it has one. Each agent call
goes in as text entries (answer, tool calls, every gate check with value and threshold,
outcome) at the simulated time it was made or judged, its proposed waypoint as a 3D point.
The recorder only reads the simulator, so a trial is the same with and without it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from actionreasoning.agents.transcript import AgentCall, CheckRecord, GateRecord, Outcome
from actionreasoning.control.classical import StageEvent
from actionreasoning.errors import ConfigError
from actionreasoning.eval.metrics import center_offset_cm
from actionreasoning.eval.rules import Method
from actionreasoning.eval.trial import TrialSpec
from actionreasoning.sim.robot_model import FINGER_LEFT
from actionreasoning.sim.scene import Scene

#: The scene is sampled every this many simulated seconds (8 Hz), and at each stage.
SAMPLE_S = 0.125
TIMELINE = "sim"
BRICK_RGBA = (204, 77, 56, 255)
TARGET_RGBA = (60, 160, 230, 70)
WAYPOINT_RGBA = (250, 200, 30, 255)
ARM_RGBA = (150, 150, 160, 255)


def require_rerun() -> None:
    """Fail early, with the fix, where the Rerun SDK is missing."""
    try:
        import rerun  # noqa: F401
    except ImportError as error:
        raise ConfigError(
            "--rerun needs the Rerun SDK: pip install 'actionreasoning[rerun]'"
        ) from error


def check_line(check: CheckRecord) -> str:
    """One gate check as text: ``name value <= threshold (pass)``."""
    verdict = "pass" if check.passed else "FAIL"
    return f"{check.name} {check.value:.4g} {check.relation} {check.threshold:.4g} ({verdict})"


def gate_text(gate: GateRecord) -> str:
    """A gate's verdict and every check behind it."""
    checks = "; ".join(check_line(c) for c in gate.checks)
    return f"{gate.gate} {'passed' if gate.passed else 'FAILED'}: {checks}"


@dataclass
class _Logged:
    """How much of one agent call is in the recording already."""

    answer: bool = False
    gates: int = 0
    outcome: bool = False


@dataclass
class RerunRecorder:
    """A :class:`~actionreasoning.eval.trial.TrialObserver` that records the trial;
    ``rrd()`` gives the recording's bytes at the end."""

    spec: TrialSpec
    every_s: float = SAMPLE_S
    _assigned: dict[int, int] = field(default_factory=dict)  # brick -> target
    _logged: dict[int, _Logged] = field(default_factory=dict)

    def __post_init__(self) -> None:
        require_rerun()
        import rerun as rr

        self._rr = rr
        name = f"{self.spec.method}-{self.spec.pattern_name}-s{self.spec.run_seed}"
        self._rec = rr.RecordingStream("actionreasoning", recording_id=f"{name}-t{self.spec.trial}")
        self._stream = self._rec.memory_recording()
        self._rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        targets = self.spec.goal.targets
        self._rec.log(
            "world/targets",
            rr.Boxes3D(
                centers=[t.pose.position_m for t in targets],
                half_sizes=[np.divide(t.size_m, 2.0) for t in targets],
                quaternions=[rr.Quaternion(xyzw=t.pose.quat_xyzw) for t in targets],
                colors=[TARGET_RGBA] * len(targets),
                labels=[f"target {t.index}" for t in targets],
                fill_mode="solid",
            ),
            static=True,
        )
        if self.spec.method is Method.CLASSICAL:  # the script puts brick k on target k
            self._assigned = {t.index: t.index for t in targets}

    # --- the observer -------------------------------------------------------------------
    def tick(self, scene: Scene) -> None:
        self._sample(scene)

    def stage(self, scene: Scene, event: StageEvent) -> None:
        self._sample(scene)
        brick = "" if event.brick < 0 else f"brick {event.brick}: "
        self._rec.log("stages", self._rr.TextLog(f"{brick}{event.stage}", level="INFO"))

    def call(self, scene: Scene, call: AgentCall) -> None:
        rr, rec = self._rr, self._rec
        self._time(scene)
        logged = self._logged.setdefault(call.call, _Logged())
        if call.brick_in_hand is not None and call.target is not None:
            self._assigned[call.brick_in_hand] = call.target
        head = f"#{call.call} {call.agent} brick {call.brick_in_hand} attempt {call.attempt}"
        if call.answer and not logged.answer:
            logged.answer = True
            rec.log(f"agents/{call.agent}", rr.TextLog(f"{head} answer: {_json(call.answer)}"))
            for tool in call.tool_calls:
                result = tool.error or _json(tool.result)
                text = f"{head} tool {tool.name}({_json(tool.arguments)}) -> {result}"
                rec.log(f"agents/{call.agent}", rr.TextLog(text, level="DEBUG"))
            waypoint = (call.answer.get("waypoint") or {}).get("position_m")
            if waypoint is not None:
                rec.log(
                    "world/waypoint",
                    rr.Points3D(
                        [waypoint], colors=[WAYPOINT_RGBA], radii=0.012, labels=[call.agent]
                    ),
                )
        for gate in call.gates[logged.gates :]:
            level = "INFO" if gate.passed else "WARN"
            rec.log("agents/gates", rr.TextLog(f"{head} {gate_text(gate)}", level=level))
        logged.gates = len(call.gates)
        if call.outcome is not Outcome.PENDING and not logged.outcome:
            logged.outcome = True
            feedback = f": {call.feedback}" if call.feedback else ""
            level = "INFO" if call.outcome in (Outcome.ACCEPTED, Outcome.EXECUTED) else "WARN"
            text = f"{head} {call.outcome}{feedback}"
            rec.log(f"agents/{call.agent}", rr.TextLog(text, level=level))

    # --- the recording ------------------------------------------------------------------
    def rrd(self) -> bytes:
        """The recording so far, as the bytes of an ``.rrd`` file."""
        self._rec.flush()
        return bytes(self._stream.drain_as_bytes())

    def _time(self, scene: Scene) -> None:
        self._rec.set_time(TIMELINE, duration=scene.time_s)

    def _sample(self, scene: Scene) -> None:
        rr, rec = self._rr, self._rec
        self._time(scene)
        poses = [scene.brick_pose(b) for b in range(len(scene.bricks))]
        rec.log(
            "world/bricks",
            rr.Boxes3D(
                centers=[pos for pos, _ in poses],
                half_sizes=[np.divide(body.size_m, 2.0) for body in scene.bodies],
                quaternions=[rr.Quaternion(xyzw=quat) for _, quat in poses],
                colors=[BRICK_RGBA] * len(poses),
                labels=[f"brick {b}" for b in range(len(poses))],
                fill_mode="solid",
            ),
        )
        tcp, quat = scene.tcp_pose()
        rec.log(
            "world/gripper", rr.Transform3D(translation=tcp, quaternion=rr.Quaternion(xyzw=quat))
        )
        rec.log("world/gripper/axes", rr.TransformAxes3D(0.08))
        links = scene.link_positions()
        rec.log("world/arm", rr.LineStrips3D([links[: FINGER_LEFT + 1]], colors=[ARM_RGBA]))
        rec.log("world/arm/links", rr.Points3D(links, radii=0.01, colors=[ARM_RGBA]))
        left, right = scene.finger_positions()
        rec.log("gripper/opening_m", rr.Scalars(left + right))
        normal = np.zeros(2)
        for brick in range(len(poses)):
            normal += [c.normal_n for c in scene.finger_contacts(brick)]
        rec.log("forces/pad_left_n", rr.Scalars(normal[0]))
        rec.log("forces/pad_right_n", rr.Scalars(normal[1]))
        held = [b for b in range(len(poses)) if scene.is_held(b)]
        if held:
            rec.log("slip/held_brick_mps", rr.Scalars(_slip(scene, held[0])))
        targets = {t.index: t.pose.position_m for t in self.spec.goal.targets}
        for brick, target in self._assigned.items():
            goal = targets[target]
            rec.log(f"offset_cm/brick_{brick}", rr.Scalars(center_offset_cm(poses[brick][0], goal)))


def _slip(scene: Scene, brick: int) -> float:
    """How fast ``brick`` moves relative to the gripper that holds it (m/s)."""
    tcp, _ = scene.tcp_pose()
    linear, angular = scene.tcp_velocity()
    position, _ = scene.brick_pose(brick)
    carried = np.asarray(linear) + np.cross(angular, np.subtract(position, tcp))
    return float(np.linalg.norm(np.subtract(scene.brick_velocity(brick)[0], carried)))


def _json(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"), default=str)
