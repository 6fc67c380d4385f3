"""Firmware-side control methods shared by every device (issue 17).

``upsampling`` : seed 000's prediction + cubic B-spline upsampling (eq 23) — an AR predictor fitted
                 online to the position history, the spline as printed and as the text intends,
                 the exact lifted analysis of the multi-rate loop and its time-domain simulation.
"""
