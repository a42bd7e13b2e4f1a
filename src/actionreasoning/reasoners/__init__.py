"""Reasoning backends behind the one-method :class:`~actionreasoning.agents.reasoner.Reasoner`."""
