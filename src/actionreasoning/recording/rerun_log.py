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
from actionreasoning.errors import ConfigError
from actionreasoning.sim.robot_model import FINGER_LEFT
from actionreasoning.sim.scene import GRASP_CONTACT_N, Scene
from actionreasoning.trial.metrics import center_offset_cm
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialObserver, TrialSpec
from actionreasoning.world.stages import StageEvent

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
class RerunRecorder(TrialObserver):
    """A trial observer that records the trial;
    ``rrd()`` gives the recording's bytes at the end, once: it ends the recording."""

    spec: TrialSpec
    every_s: float = SAMPLE_S
    _assigned: dict[int, int] = field(default_factory=dict)  # brick -> target
    _logged: dict[int, _Logged] = field(default_factory=dict)
    _times: list[float] = field(default_factory=list)  # of the samples
    _rows: dict[str, list[Any]] = field(default_factory=dict)  # a row per sample
    _scalars: dict[str, tuple[list[float], list[Any]]] = field(default_factory=dict)

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
        self._time(scene)
        brick = "" if event.brick < 0 else f"brick {event.brick}: "
        self._rec.log("stages", self._rr.TextLog(f"{brick}{event.stage}", level="INFO"))

    def call(self, scene: Scene, call: AgentCall) -> None:
        rr, rec = self._rr, self._rec
        self._time(scene)
        logged = self._logged.setdefault(call.call, _Logged())
        if call.brick_in_hand is not None and call.target is not None:
            self._assigned[call.brick_in_hand] = call.target
        head = f"#{call.call} {call.agent} brick {call.brick_in_hand} attempt {call.attempt}"
        if (call.answer or call.outcome is not Outcome.PENDING) and not logged.answer:
            logged.answer = True  # a call that failed has its tool calls but no answer
            if call.answer:
                answer = f"{head} answer: {_json(call.answer)}"
                rec.log(f"agents/{call.agent}", rr.TextLog(answer))
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
        """The recording, as the bytes of an ``.rrd`` file; this ends the recording."""
        self._send_samples()
        self._rec.flush()
        data = bytes(self._stream.drain_as_bytes())
        self._release()
        return data

    def _send_samples(self) -> None:
        """The samples go in here, in columns: logged one by one they would cost a third of
        the trial's time."""
        rr, rec, rows = self._rr, self._rec, len(self._times)
        if rows:
            index = [rr.TimeColumn(TIMELINE, duration=self._times)]
            bricks = len(self._rows["centers"][0])
            rec.send_columns(
                "world/bricks",
                indexes=index,
                columns=rr.Boxes3D.columns(
                    centers=np.reshape(self._rows["centers"], (-1, 3)),
                    quaternions=np.reshape(self._rows["quats"], (-1, 4)),
                ).partition([bricks] * rows),
            )
            rec.send_columns(
                "world/gripper",
                indexes=index,
                columns=rr.Transform3D.columns(
                    translation=self._rows["tcp"], quaternion=self._rows["tcp_quat"]
                ),
            )
            rec.send_columns(
                "world/arm",
                indexes=index,
                columns=rr.LineStrips3D.columns(strips=self._rows["arm"]).partition([1] * rows),
            )
        for entity, (times, values) in self._scalars.items():
            index = [rr.TimeColumn(TIMELINE, duration=times)]
            rec.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=values))

    def _release(self) -> None:
        """Free the stream's threads and buffers now, not at the process's exit. The memory
        sink holds its stream, so ``disconnect`` first breaks that cycle; the SDK then keeps
        the orphaned stream, threads and all, until ``rr.init`` destroys orphaned recordings
        (its documented side effect; ``init_logging=False`` makes no new recording)."""
        self._rec.disconnect()
        del self._stream, self._rec
        self._rr.init("actionreasoning", init_logging=False)

    def _time(self, scene: Scene) -> None:
        self._rec.set_time(TIMELINE, duration=scene.time_s)

    def _scalar(self, entity: str, time_s: float, value: Any) -> None:
        times, values = self._scalars.setdefault(entity, ([], []))
        times.append(time_s)
        values.append(value)

    def _sample(self, scene: Scene) -> None:
        """Keep the scene's state now; ``rrd()`` sends it."""
        if not self._times:
            self._log_static(scene)
        now = scene.time_s
        self._times.append(now)
        poses = [scene.brick_pose(b) for b in range(len(scene.bricks))]
        tcp, quat = scene.tcp_pose()
        for name, row in (
            ("centers", [pos for pos, _ in poses]),
            ("quats", [q for _, q in poses]),
            ("tcp", tcp),
            ("tcp_quat", quat),
            ("arm", scene.link_positions()[: FINGER_LEFT + 1]),
        ):
            self._rows.setdefault(name, []).append(row)
        self._scalar("gripper/opening_m", now, sum(scene.finger_positions()))
        pads = [scene.finger_contacts(b) for b in range(len(poses))]
        self._scalar("forces/pad_n", now, [sum(p[side].normal_n for p in pads) for side in (0, 1)])
        held = [b for b, p in enumerate(pads) if all(c.normal_n > GRASP_CONTACT_N for c in p)]
        if held:
            self._scalar("slip/held_brick_mps", now, _slip(scene, held[0]))
        targets = {t.index: t.pose.position_m for t in self.spec.goal.targets}
        for brick, target in self._assigned.items():
            offset = center_offset_cm(poses[brick][0], targets[target])
            self._scalar(f"offset_cm/brick_{brick}", now, offset)

    def _log_static(self, scene: Scene) -> None:
        """What does not change over the trial: the bricks' sizes, colours and names, the
        gripper's axes, the arm's colour, the names of the pad forces."""
        rr, rec, count = self._rr, self._rec, len(scene.bricks)
        rec.log(
            "world/bricks",
            rr.Boxes3D.from_fields(
                half_sizes=[np.divide(body.size_m, 2.0) for body in scene.bodies],
                colors=[BRICK_RGBA] * count,
                labels=[f"brick {b}" for b in range(count)],
                fill_mode="solid",
            ),
            static=True,
        )
        rec.log("world/gripper/axes", rr.TransformAxes3D(0.08), static=True)
        rec.log("world/arm", rr.LineStrips3D.from_fields(colors=[ARM_RGBA]), static=True)
        rec.log("forces/pad_n", rr.SeriesLines(names=["left pad", "right pad"]), static=True)


def _slip(scene: Scene, brick: int) -> float:
    """How fast ``brick`` moves relative to the gripper that holds it (m/s)."""
    tcp, _ = scene.tcp_pose()
    linear, angular = scene.tcp_velocity()
    position, _ = scene.brick_pose(brick)
    carried = np.asarray(linear) + np.cross(angular, np.subtract(position, tcp))
    return float(np.linalg.norm(np.subtract(scene.brick_velocity(brick)[0], carried)))


def _json(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"), default=str)
