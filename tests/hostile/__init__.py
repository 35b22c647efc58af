"""The hostile-input corpus: every boundary, each case run through ``app.cli.main`` and classified."""
