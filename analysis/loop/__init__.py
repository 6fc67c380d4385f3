"""The closed loop, shared by every device: scenes, the plant protocol, traces, operator, MuJoCo settings."""
