"""Firmware-side control methods shared by every device (shared analysis floor).

``upsampling``          : seed 000's prediction + cubic B-spline upsampling (eq 23) — an AR
                          predictor fitted online to the position history, the spline as printed
                          and as the text intends, the exact lifted analysis of the multi-rate
                          loop and its time-domain simulation.
``impedance_learning``  : seed 001's iterative optimal impedance (IOIC): the LQR optimum of eq 6,
                          off-policy policy iteration from interaction data, the soft switch.
``ioic_online``         : the IOIC outer loop as firmware, learning tick by tick (both devices).
``sliding_mode``        : seed 001's nonsingular terminal sliding-mode tracking control (NTSMTC).
``two_link``            : seed 001's two-link arm (Table 1), the reference plant of its examples.
"""
