"""The world model: scene specification, bricks, goal patterns and the typed WorldState."""
