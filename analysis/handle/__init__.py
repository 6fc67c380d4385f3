"""Seed 000's force-feedback handle, per axis (issue 17): the third device column.

``model``       : the handle, the operator (``analysis.loop.operator.Operator``), the virtual wall and the
                 sampling period as one frozen value in SI (``from_design``); continuous state space
                 with/without the operator; exact ZOH and the paper's Padé hold 2/(2 + sT).
``stability``   : eq (15)–(19) and (20)–(22) closed forms, the exact sampled-loop boundary, the Z-width
                 map, ``max_stable_stiffness_N_per_mm``; the registry evaluator ``stability``.
``upsampled``   : registry evaluator ``upsampling``: lifted limits per eq (23) variant.
``zwidth``      : registry evaluator ``zwidth`` (the map; its picture in ``plots``).
``firmware``    : the scene firmware (wall at measured/predicted positions, eq 23 spline).
``closed_loop`` : the handle's scenes (``hapticopt verify``).
"""
