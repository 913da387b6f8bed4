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
from .roots import CMU_CLIPS, EMBEDDED_ROOT, DataNotFoundError, find_data_root, is_embedded

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
    "is_embedded",
    "EMBEDDED_ROOT",
    "CMU_CLIPS",
    "DataNotFoundError",
]
