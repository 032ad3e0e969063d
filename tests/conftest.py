import jax
import pytest

# Tests run in float64 (accuracy and gradient checks) with silent broadcasting off.
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(1234)
