"""Finding data, the clip catalogue and the committed train/test splits."""

from .catalogue import (
    SPLITS,
    Clip,
    catalogue,
    dataset_terms,
    find_clip,
    has_reference_frame,
    select,
    share,
    without_reference_frame,
)
from .roots import DataNotFoundError, find_data_root

__all__ = [
    "SPLITS",
    "Clip",
    "catalogue",
    "dataset_terms",
    "find_clip",
    "select",
    "share",
    "has_reference_frame",
    "without_reference_frame",
    "find_data_root",
    "DataNotFoundError",
]
