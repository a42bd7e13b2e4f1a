"""Feedback as data: what a gate measured when it refused an answer, signed and in the world
frame, so that the next answer can correct by it.

A :class:`Refusal` goes into the task memory M_t (typed, for reasoners; rendered as JSON in
the prompt, for a model) beside the one-line text a model reads first. Its errors are
"wanted minus measured": shifting or turning the next answer by them moves the brick (or
the tool) to where it should have been.
"""

from __future__ import annotations

from collections.abc import Sequence

from pydantic import BaseModel, ConfigDict, Field

#: Errors are shown to 0.01 mm and 0.001 deg: what the gates compare.
ERROR_DIGITS = 5


class _Data(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Measured(_Data):
    """What a gate measured, signed, in the world frame (None: not measured by this gate)."""

    e_x_m: float | None = Field(
        None, description="Wanted minus measured x of the brick's centre: shift by this."
    )
    e_y_m: float | None = Field(None, description="The same along y.")
    e_z_m: float | None = Field(None, description="The same along z (up).")
    e_theta_deg: float | None = Field(
        None, description="Wanted minus measured yaw, wrapped to [-180, 180): turn by this."
    )
    d_perp_m: float | None = Field(
        None, description="Height of the brick's bottom above its seat (> 0: too high)."
    )
    tilt_deg: float | None = Field(
        None, description="Roll of the brick in the hand (or its tilt on the seat), 0 to 90."
    )
    pad_forces_n: tuple[float, float] | None = Field(None, description="Normal force on each pad.")
    slip_speed_mps: float | None = Field(
        None, description="Speed of the brick relative to the gripper."
    )
    move_speed_mps: float | None = Field(
        None, description="Mean speed of the move just made (its length over its duration)."
    )
    clearance_m: float | None = Field(
        None, description="Least clearance of the path checked (< 0: overlap)."
    )
    closest: str | None = Field(None, description="The two things that came closest.")


class FailedCheck(_Data):
    """One check of a gate that failed: its measured value against its threshold."""

    name: str
    value: float
    relation: str = Field(description="'<=' or '>=': how the value must stand to pass.")
    threshold: float


class Refusal(_Data):
    """Why an answer was refused: the gate or check, what failed, and what was measured."""

    agent: str = Field(description="The agent whose answer was refused.")
    gate: str = Field(description="The gate or pre-move check that refused it.")
    failed: tuple[FailedCheck, ...] = ()
    measured: Measured = Measured()
    note: str = Field("", description="What happened, in words (e.g. how a set-down ended).")

    def text(self) -> str:
        """The refusal as one line for a model: the failed checks, then the measurements."""
        checks = "; ".join(
            f"{c.name} = {c.value:.4g}, needs {c.relation} {c.threshold:.4g}" for c in self.failed
        )
        parts = [f"{self.gate} failed: {checks}" if checks else self.gate]
        if self.note:
            parts.append(self.note)
        measured = describe(self.measured)
        if measured:
            parts.append(f"measured (world frame, wanted minus measured): {measured}")
        return "; ".join(parts)


def describe(measured: Measured) -> str:
    """The measurements that were made, as ``name=value`` pairs."""
    values = measured.model_dump(exclude_none=True)
    return ", ".join(
        f"{name}={_fmt(value)}" for name, value in values.items() if name != "closest"
    ) + (f", closest: {measured.closest}" if measured.closest else "")


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:+.5g}"
    if isinstance(value, tuple | list):
        return "(" + ", ".join(f"{v:.4g}" for v in value) + ")"
    return str(value)


#: Gates whose refusal put the brick down to be grasped again.
PUT_DOWN_GATES = ("sigma4_lift", "placement_regrasp")


def since_put_down(refusals: Sequence[Refusal]) -> Sequence[Refusal]:
    """The refusals since the brick was last put down to be grasped again (all of them if
    it never was): those of its present grasp."""
    put_down = [i for i, r in enumerate(refusals) if r.gate in PUT_DOWN_GATES]
    return refusals[put_down[-1] + 1 :] if put_down else refusals
