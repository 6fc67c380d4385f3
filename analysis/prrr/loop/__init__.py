"""3-PRRR loop."""
