"""Which tier each notebook runs in, and the order in which the two test workers
take the files (pyproject's addopts run `--dist loadfile --no-loadscope-reorder`:
each file runs whole on one worker, the files handed out in the order of the
collected items).

The notebooks (nbmake, one test each) run in the slow tier (`-m slow`, which CI
runs after the default suite): at toy size each still takes 30-140 s on two
cores, nearly all of it XLA compiling the gradients and sweeps the notebook
shows, a third of the default suite's time for a check that every cell runs.

Longest first, so that the workers finish together: the notebooks, then the test
modules by their number of tests, most first (xdist's own order put the
notebooks last, where one worker ran them while the other had nothing left)."""

import collections

import pytest


@pytest.hookimpl(tryfirst=True)  # before `-m` deselects by marker
def pytest_collection_modifyitems(session, config, items):
    del session, config
    for item in items:
        if item.path.suffix == ".ipynb":
            item.add_marker(pytest.mark.slow)
    count = collections.Counter(item.path for item in items)

    def key(item):
        return (item.path.suffix != ".ipynb", -count[item.path], str(item.path))

    items.sort(key=key)  # stable: a file's own order is kept
