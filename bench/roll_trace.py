"""A held brick's roll in the hand through one built-in trial, every 25 ms of simulated time:
where the roll that ends a trial happens, and what the brick touches then.

    .venv/bin/python bench/roll_trace.py --seed 5 --trial 0 --pattern grid --brick 3

Runs the trial (paper physics, no noise, the built-in reasoner in the default tier) and,
while brick ``--brick`` is held, prints the state time, the agent call under way, the
brick's roll in the hand about the pads' axis (``formulas.roll_in_hand_deg``), its centre
in the tool frame (mm: x along the pads, y across, z down), the tool's tilt from pointing
down, the tool centre point, and the bodies (with link) in contact with the brick.
"""

from __future__ import annotations

import argparse

import numpy as np
import pybullet as p

from actionreasoning.agents.transcript import AgentCall
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.sim.scene import Scene
from actionreasoning.tools import formulas
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialObserver, TrialSpec, run_trial
from actionreasoning.world.geometry import tilt_deg
from actionreasoning.world.models import Pose
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec

#: Simulated seconds between two lines.
EVERY_S = 0.025
#: Contacts closer than this (m) are listed.
TOUCH_M = 0.002


class RollTrace(TrialObserver):
    """Prints the held brick's roll and contacts (see the module docstring)."""

    every_s = EVERY_S

    def __init__(self, brick: int) -> None:
        self.brick = brick
        self.asking = "start"  # the agent call under way

    def call(self, scene: Scene, call: AgentCall) -> None:
        self.asking = f"{call.agent}#{call.call}"

    def tick(self, scene: Scene) -> None:
        if not scene.is_held(self.brick):
            return
        tcp_p, tcp_q = scene.tcp_pose()
        brick_p, brick_q = scene.brick_pose(self.brick)
        tool = Pose(position_m=tcp_p, quat_xyzw=tcp_q)
        offset, quat = formulas.in_hand(tool, Pose(position_m=brick_p, quat_xyzw=brick_q))
        names = {scene.robot: "robot", scene.ground: "ground"}
        names.update({body: f"brick {i}" for i, body in enumerate(scene.bricks)})
        contacts = p.getContactPoints(bodyA=scene.bricks[self.brick], physicsClientId=scene.client)
        touching = sorted({f"{names.get(c[2], c[2])}:{c[4]}" for c in contacts if c[8] < TOUCH_M})
        mm = np.multiply(offset, 1000.0)
        seconds = scene.ticks * scene.physics.time_step_s
        print(
            f"{seconds:8.3f} {self.asking:16s} roll {formulas.roll_in_hand_deg(quat):7.1f} deg  "
            f"centre ({mm[0]:6.1f}, {mm[1]:5.1f}, {mm[2]:5.1f}) mm  "
            f"tool tilt {tilt_deg(tcp_q):5.1f} deg  tcp ({tcp_p[0]:.3f}, {tcp_p[1]:.3f}, "
            f"{tcp_p[2]:.3f})  {' '.join(touching)}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--trial", type=int, default=0)
    parser.add_argument("--pattern", default="grid")
    parser.add_argument("--brick", type=int, default=3)
    args = parser.parse_args()
    goal = load_pattern(args.pattern, SceneSpec())
    config = TrialConfig(llm=LLMConfig(spec="builtin"))
    spec = TrialSpec(Method.AGENTS, args.pattern, goal, args.seed, args.trial, config)
    run = run_trial(spec, [RollTrace(args.brick)])
    failure = run.result.failure
    print("success" if run.result.success else f"failed: {failure.reason if failure else ''}")


if __name__ == "__main__":
    main()
