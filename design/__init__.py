"""Design descriptions of haptic mechanisms: frozen values, SI inside.

Devices: :class:`design.prrr.PrrrDesign` (seed 002's 3-PRRR) and
:class:`design.master.MasterDesign` (seed 003's PHANToM-type surgical master).
Load/save with :mod:`design.io`.
"""
