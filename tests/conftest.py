import jax
import pytest

# Tests run in float64 (accuracy and gradient checks) with silent broadcasting off.
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(1234)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop each module's compiled programs when it ends. The whole suite in one
    process otherwise holds thousands of XLA executables, and their memory mappings
    approach the kernel's default per-process limit (vm.max_map_count = 65530)."""
    yield
    jax.clear_caches()
