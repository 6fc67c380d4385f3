"""Evaluators, firmware controller, plants and scenes of hapticopt.

jax runs in float64 here: it must be switched on before any jax array exists, so it is done
on import of this package (every numeric module lives under it).
"""

import jax

jax.config.update("jax_enable_x64", True)
