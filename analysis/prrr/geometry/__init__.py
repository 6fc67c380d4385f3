"""3-PRRR geometry."""
