"""Every failure reason the code can write is in the one table of codes (records.py), so
summaries, reports and the README explain each one."""

from __future__ import annotations

import re
from pathlib import Path

from actionreasoning.records import FAILURE_CODES

SOURCE = Path(__file__).resolve().parents[1] / "src" / "actionreasoning"
RAISED = re.compile(
    r"(?:reason=|reason = |TrialStopped\(|TrialAborted\(|LLMError\(|_Refused\([^)]*?,\s*"
    r"|_gate\([^,]*,\s*|UnreachableError\) else )\s*\"([a-z_]+)\""
)


def test_every_reason_in_the_code_is_a_documented_code() -> None:
    found = {code for path in SOURCE.rglob("*.py") for code in RAISED.findall(path.read_text())}
    assert len(found) >= 20  # the pattern still finds the raise sites
    assert found <= set(FAILURE_CODES), found - set(FAILURE_CODES)
    readme = (SOURCE.parents[1] / "README.md").read_text()
    assert all(f"| `{code}` | {meaning} |" in readme for code, meaning in FAILURE_CODES.items())
