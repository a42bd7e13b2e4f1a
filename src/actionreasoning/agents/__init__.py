"""The six gated agents: specs, prompts, gates and the orchestrator (no PyBullet here)."""
