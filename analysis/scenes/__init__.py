"""Bundled closed-loop scenes (TOML package data); see ``analysis.scene`` for the schema."""
