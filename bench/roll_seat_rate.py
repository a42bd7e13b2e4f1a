"""How often a set-down tilted to make up for a brick's roll in the hand seats it, by roll;
and how often a re-grasp that Ag5 asked for saves the brick: whether Ag5 should grasp a
far-rolled brick again rather than tilt the tool by its roll.

    .venv/bin/python bench/roll_seat_rate.py runs/noise/agents-* [--bin 5]

Reads the transcripts of agents runs (``eval --transcripts``): every set-down call whose
``placement_pose`` measured the brick's roll in the hand, and whether sigma_5 accepted
it; every re-grasp Ag5 asked for, and whether its target was built after all.
"""

from __future__ import annotations

import argparse
import collections
import json
from collections.abc import Iterator
from pathlib import Path


def calls(runs: list[Path]) -> Iterator[list[dict]]:
    """Every trial transcript of the runs, as its list of calls."""
    for run in runs:
        for path in sorted((run / "transcripts").glob("trial_*.jsonl")):
            yield [json.loads(line) for line in path.read_text().splitlines()]


def set_downs(trial: list[dict]) -> Iterator[tuple[float, bool]]:
    """(roll in the hand, deg; seated) for each set-down that sigma_5 judged."""
    for call in trial:
        if not any(g["gate"] == "sigma5_placement" for g in call.get("gates") or []):
            continue
        rolls = [
            t["result"]["tilt_in_hand_deg"]
            for t in call["tool_calls"]
            if t["name"] == "placement_pose" and t.get("result")
        ]
        if rolls:
            yield abs(rolls[-1]), call["outcome"] == "accepted"


def regrasps_saved(trial: list[dict]) -> Iterator[bool]:
    """For each re-grasp Ag5 asked for: whether its target was built in the end."""
    for i, call in enumerate(trial):
        if call["agent"] == "placement" and call["outcome"] == "regrasp":
            yield any(
                later["target"] == call["target"]
                and later["outcome"] == "accepted"
                and any(g["gate"] == "sigma5_placement" for g in later.get("gates") or [])
                for later in trial[i + 1 :]
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="agents run directories")
    parser.add_argument("--bin", type=float, default=5.0, help="roll bin width, deg")
    args = parser.parse_args()
    seated: dict[int, list[bool]] = collections.defaultdict(list)
    saved: list[bool] = []
    for trial in calls(args.runs):
        for roll, ok in set_downs(trial):
            seated[int(roll // args.bin)].append(ok)
        saved.extend(regrasps_saved(trial))
    print("roll in the hand (deg) | set-downs | seated")
    for b in sorted(seated):
        n, ok = len(seated[b]), sum(seated[b])
        print(f"{b * args.bin:5.0f}-{(b + 1) * args.bin:<5.0f}| {n:9d} | {ok / n:6.0%}")
    if saved:
        rate = sum(saved) / len(saved)
        print(f"re-grasps Ag5 asked for: {len(saved)}, target built after: {rate:.0%}")


if __name__ == "__main__":
    main()
