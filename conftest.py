"""The order in which the two test workers take the files (pyproject's addopts run
`--dist loadfile --no-loadscope-reorder`: each file runs whole on one worker, the
files handed out in the order of the collected items).

Longest first, so that the workers finish together: the notebooks (one test each,
but 25-120 s, most of it XLA compilation in the kernel), then the test modules by
their number of tests, most first (xdist's own order, which put the notebooks last,
where one worker ran them while the other had nothing left)."""

import collections


def pytest_collection_modifyitems(session, config, items):
    del session, config
    count = collections.Counter(item.path for item in items)

    def key(item):
        return (item.path.suffix != ".ipynb", -count[item.path], str(item.path))

    items.sort(key=key)  # stable: a file's own order is kept
