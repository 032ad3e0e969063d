"""pytest runs every notebook here (nbmake, see pyproject.toml) at toy size.

The kernels nbmake starts inherit this process's environment, so setting it when
pytest loads this file reaches every notebook. JAXMPS_NOTEBOOK_SMOKE=1 makes each
notebook's first code cell pick toy sizes (the run checks that every cell executes,
not the physics), and figures go to the Agg backend, which needs no display.
`JAXMPS_NOTEBOOK_SMOKE=0` runs the full studies instead, with the kernel's own
inline backend so that `--overwrite` keeps the figures.
"""

import os

os.environ.setdefault("JAXMPS_NOTEBOOK_SMOKE", "1")
if os.environ["JAXMPS_NOTEBOOK_SMOKE"] not in ("", "0"):
    os.environ["MPLBACKEND"] = "Agg"
