"""Seed 000's force-feedback handle: one axis of the 3-DOF handle, its firmware and the wall it renders."""
