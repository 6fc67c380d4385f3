"""3-PRRR structure."""
