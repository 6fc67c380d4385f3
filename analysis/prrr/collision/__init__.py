"""3-PRRR collision."""
