"""Run files: HDF5 (the layout in docs/architecture.md) with an XDMF sidecar for
ParaView."""

from ._hdf5 import FORMAT as FORMAT
from ._hdf5 import FORMAT_VERSION as FORMAT_VERSION
from ._hdf5 import RUN_STATUSES as RUN_STATUSES
from ._hdf5 import RunData as RunData
from ._hdf5 import RunWriter as RunWriter
from ._hdf5 import load_state as load_state
from ._hdf5 import read_run as read_run
from ._hdf5 import write_run as write_run
from ._hdf5 import write_xdmf as write_xdmf
