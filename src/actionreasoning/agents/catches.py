"""What caught each corrupted answer, and which checks refused answers nobody corrupted.

Read from a trial's transcript (``GateRecord.enforced``: the rung let the verdict refuse;
``GateRecord.after_move``: it judged a move that had run). A corrupted answer was caught
``before`` the move (an enforced failed verdict judged before it: validation, a pre-move
check, sigma_1 or sigma_6), ``after`` it (an enforced failed gate sigma_2..sigma_5 refused,
raised or put it down), ``missed`` (it ran: accepted, or executed past a check the rung does
not enforce), or the trial stopped on it (``trial_stopped``: it failed or was never judged).
A miss is followed to what it led to (:func:`led_to`) and to the check that would have
caught it on another rung (``would_catch``). Answers nobody corrupted that a pre-move check,
sigma_1 or sigma_6 refused are counted apart (:func:`premove_refusals`): each is a check
refusing an answer its reasoner believed right.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Sequence
from dataclasses import dataclass

from actionreasoning.agents.answer_errors import Caught, CorruptionKind
from actionreasoning.agents.transcript import AgentCall, GateRecord, Outcome
from actionreasoning.agents.verification import CheckKind, kind_of
from actionreasoning.records import Failure, FailureCode
from actionreasoning.world.stages import Stage

#: What a missed answer led to when nothing later refused anything and its brick was placed
#: within the success rule (or the trial went on without placing it, and ended well).
HARMLESS = "harmless"
#: The single agent's key: its calls name their step in the answer.
SINGLE_AGENT = "single_agent"


@dataclass(frozen=True)
class Catch:
    """What became of one corrupted answer: its kind, whether it repeated a refused
    mistake, where it was caught and by which check (``gate:check``; for a refusal that no
    verdict records, the outcome); for a miss, what it led to and what would have caught it
    (the first failed verdict its rung did not enforce, if any)."""

    kind: CorruptionKind
    caught: Caught
    check: str | None = None
    led_to: str | None = None
    would_catch: str | None = None
    repeated: bool = False


def named(gate: GateRecord) -> str:
    """A verdict as ``gate:check``, its first failed check (the gate alone if none failed)."""
    check = next((c.name for c in gate.checks if not c.passed), None)
    return gate.gate if check is None else f"{gate.gate}:{check}"


def refused_by(call: AgentCall) -> GateRecord | None:
    """The verdict that stopped the call's answer: its last enforced failed one."""
    return next((g for g in reversed(call.gates) if g.enforced and not g.passed), None)


def catches(
    transcript: Sequence[AgentCall],
    failure: Failure | None = None,
    misplaced: Collection[int] = (),
) -> list[Catch]:
    """What became of every corrupted answer of a trial, in call order; ``failure`` is the
    trial's, ``misplaced`` the bricks that ended outside the success rule (for
    :func:`led_to`)."""
    return [
        catch_of(transcript, index, failure, misplaced)
        for index, call in enumerate(transcript)
        if call.corruption is not None
    ]


def catch_of(
    transcript: Sequence[AgentCall],
    index: int,
    failure: Failure | None = None,
    misplaced: Collection[int] = (),
) -> Catch:
    """What became of the corrupted answer of ``transcript[index]``."""
    call = transcript[index]
    assert call.corruption is not None
    kind, repeated = call.corruption.kind, call.corruption.repeated
    if call.outcome in (Outcome.FAILED, Outcome.PENDING):
        return Catch(kind, Caught.TRIAL_STOPPED, repeated=repeated)
    if call.outcome in (Outcome.ACCEPTED, Outcome.EXECUTED):
        unenforced = next((g for g in call.gates if not g.enforced and not g.passed), None)
        return Catch(
            kind,
            Caught.MISSED,
            led_to=led_to(transcript, index, failure, misplaced),
            would_catch=None if unenforced is None else named(unenforced),
            repeated=repeated,
        )
    gate = refused_by(call)
    if gate is None:  # refused without a verdict on record
        return Catch(kind, Caught.BEFORE, str(call.outcome), repeated=repeated)
    caught = Caught.AFTER if gate.after_move else Caught.BEFORE
    return Catch(kind, caught, named(gate), repeated=repeated)


def led_to(
    transcript: Sequence[AgentCall],
    index: int,
    failure: Failure | None = None,
    misplaced: Collection[int] = (),
) -> str:
    """What the answer of ``transcript[index]``, which ran, led to: the first enforced failed
    verdict later in its brick's cycle (up to the release that placed the brick), as
    ``gate:check``; else, if the trial ended before the brick was placed, the trial's
    failure reason; else ``misplaced`` if the brick ended outside the success rule (in
    ``misplaced``), else :data:`HARMLESS`."""
    call = transcript[index]
    placed = _places(call)
    for later in transcript[index + 1 :]:
        if placed:
            break
        gate = refused_by(later)
        if gate is not None:
            return named(gate)
        placed = _places(later)
    if not placed:
        return HARMLESS if failure is None else str(failure.reason)
    return str(FailureCode.MISPLACED) if call.brick_in_hand in misplaced else HARMLESS


def premove_refusals(transcript: Sequence[AgentCall]) -> dict[str, int]:
    """Answers nobody corrupted that an enforced pre-move check, sigma_1 or sigma_6 refused
    (validation of the answer as data, and the gates judged after a move, left out), by
    ``gate:check``, sorted by name."""
    counts = Counter[str]()
    for call in transcript:
        gate = refused_by(call)
        if (
            call.corruption is None
            and call.outcome is Outcome.REFUSED
            and gate is not None
            and not gate.after_move
            and kind_of(gate.gate) is not CheckKind.VALIDATION
        ):
            counts[named(gate)] += 1
    return dict(sorted(counts.items()))


def _places(call: AgentCall) -> bool:
    """Whether the call's answer released its brick on the build (Ag6's, or the single
    agent's release step, that ran)."""
    step = call.answer.get("step") if call.agent == SINGLE_AGENT else call.agent
    return step == Stage.RELEASE and call.outcome in (Outcome.ACCEPTED, Outcome.EXECUTED)
