"""Host-side geometry builders (NumPy). Never imported by the jitted core."""

from ._lattice import block as block
from ._lattice import layers_for as layers_for
from ._lattice import packed_bed as packed_bed
from ._lattice import plate as plate
from ._lattice import remove_overlaps as remove_overlaps
from ._lattice import tank as tank
