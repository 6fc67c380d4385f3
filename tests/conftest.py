"""Shared test fixtures. jax float64 is switched on by importing ``analysis``."""

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import pytest
from hypothesis import settings

settings.register_profile("ci", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("ci")


@pytest.fixture(scope="session")
def prrr_paper():
    from hapticopt.design import io

    return io.load_preset("prrr-paper")


@pytest.fixture(scope="session")
def master_paper():
    from hapticopt.design import io

    return io.load_preset("master-paper")


def pytest_report_header(config):
    """The BLAS kernels in use (``make hardcases`` runs the hard cases under two of them)."""
    try:
        import numpy  # noqa: F401  (loads numpy's OpenBLAS)
        from threadpoolctl import threadpool_info
    except ImportError:
        return None
    kernels = sorted({f"{i.get('internal_api')} {i.get('architecture')}" for i in threadpool_info()
                      if i.get("user_api") == "blas"})
    return "BLAS kernels: " + (", ".join(kernels) or "unknown")
