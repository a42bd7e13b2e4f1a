"""One trial: the scene, the method that builds in it, its score, and the session that
opens a trial to a caller outside (the Gym env, the MCP server)."""
