"""Design descriptions of haptic mechanisms: frozen values, SI inside.

Devices: :class:`hapticopt.design.prrr.params.PrrrDesign` (seed 002's 3-PRRR) and
:class:`hapticopt.design.master.params.MasterDesign` (seed 003's PHANToM-type surgical master).
Load/save with :mod:`design.io`.
"""
