"""Bundled closed-loop scenes (TOML package data); see ``hapticopt.analysis.loop.scene`` for the schema."""
