"""jax configuration for all of hapticopt: float64, and compiled code cached on disk.

Every module that uses jax imports this module first (``from hapticopt.design import
jax_config  # noqa: F401``), so float64 never depends on which package happened to be imported
before (tests/test_layers.py checks it). It must run before any jax array exists.

jit compilation dominates a short CLI call (pitfalls: jax), so compiled code is kept on disk:
directory ``$HAPTICOPT_JAX_CACHE`` or ``~/.cache/hapticopt/jax``; an empty value switches the
cache off.
"""

import os

import jax

jax.config.update("jax_enable_x64", True)

_cache = os.environ.get("HAPTICOPT_JAX_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "hapticopt", "jax"))
if _cache and jax.config.jax_compilation_cache_dir is None:
    jax.config.update("jax_compilation_cache_dir", _cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
