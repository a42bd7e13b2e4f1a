"""The knowledge base K: typed tools over the WorldState that Python code and LLMs both call."""
