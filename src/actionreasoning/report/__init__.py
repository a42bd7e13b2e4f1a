"""`actionreasoning report`: eval runs side by side, as tables, plots, pictures and a page."""
