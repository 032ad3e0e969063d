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
    """Drop each module's compiled programs when it ends. Without this, the whole
    suite in one process (5.9 GB peak RSS) died twice with a segmentation fault
    inside XLA's compiler at the same test (test_step.py, after ~160 tests), which
    passes alone and with its neighbours. Our reading, not proven: the thousands
    of executables held exhaust the per-process memory mappings (with this
    clearing the count peaks at 13.5k of the default vm.max_map_count = 65530)."""
    yield
    jax.clear_caches()
