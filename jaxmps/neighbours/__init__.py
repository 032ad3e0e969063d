"""Neighbour search: sort-based cell hashing with fixed capacities."""

from ._grid import Grid as Grid
from ._grid import candidate_counts as candidate_counts
from ._list import NeighbourCache as NeighbourCache
from ._list import Neighbours as Neighbours
from ._list import build as build
from ._list import carried_search as carried_search
from ._list import cell_coordinates as cell_coordinates
from ._list import lists_hold as lists_hold
from ._list import reuse_or_build as reuse_or_build
from ._list import search as search
