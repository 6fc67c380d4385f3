"""Seed 000's force-feedback handle, per axis (issue 17).

``model``     : the handle, the operator of eq (1), the virtual wall and the sampling period as one
               frozen value in SI; continuous state space with/without the operator; exact ZOH and
               the paper's Padé hold 2/(2 + sT).
``stability`` : eq (15)–(19) and (20)–(22) closed forms, the exact sampled-loop boundary, the
               Z-width map and ``max_stable_stiffness_N_per_mm``.

Imports numpy/scipy and the shared control methods only.
"""
