"""Which DICOM objects are segmentations: DICOM SEG (binary/fractional, and the Label Map SOP class)
and RT Structure Sets; used by the folder scan to keep them apart from image slices."""
from __future__ import annotations

SEG_STORAGE = "1.2.840.10008.5.1.4.1.1.66.4"
LABEL_MAP_SEG_STORAGE = "1.2.840.10008.5.1.4.1.1.66.7"
RTSTRUCT_STORAGE = "1.2.840.10008.5.1.4.1.1.481.3"
#: SOP class UID → kind
SEGMENTATION_CLASSES = {SEG_STORAGE: "SEG", LABEL_MAP_SEG_STORAGE: "SEG (label map)",
                        RTSTRUCT_STORAGE: "RTSTRUCT"}


def segmentation_kind(ds) -> str:
    """``"SEG"``, ``"SEG (label map)"``, ``"RTSTRUCT"`` for a segmentation object, else ``""``."""
    sop = str(ds.get("SOPClassUID", "") or "")
    if not sop:
        meta = getattr(ds, "file_meta", None)
        sop = str(meta.get("MediaStorageSOPClassUID", "") or "") if meta is not None else ""
    if sop in SEGMENTATION_CLASSES:
        return SEGMENTATION_CLASSES[sop]
    modality = str(ds.get("Modality", "") or "")
    return {"SEG": "SEG", "RTSTRUCT": "RTSTRUCT"}.get(modality, "")
