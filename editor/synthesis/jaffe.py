"""The JAFFE data set's naming, defined once: expression codes and the images of a folder.

JAFFE (research-only, never shipped) names its images ``PERSON.CODEn.ID.tiff``, e.g.
``KA.HA1.29.tiff``: person ``KA``, happy, instance 1. :data:`JAFFE_CODES` orders the codes as the
bilinear model's expression labels (label k <-> ``JAFFE_CODES[k]``); :data:`JAFFE_EMOTIONS` maps
the six non-neutral codes to FAP Studio's emotion preset names.
"""

from __future__ import annotations

from pathlib import Path

#: JAFFE expression codes; index = the bilinear model's expression label.
JAFFE_CODES = ("NE", "HA", "SA", "SU", "AN", "DI", "FE")
#: Non-neutral JAFFE code -> emotion preset name, in :data:`JAFFE_CODES` order.
JAFFE_EMOTIONS = dict(zip(JAFFE_CODES[1:], ("joy", "sadness", "surprise", "anger", "disgust",
                                            "fear"), strict=True))


def jaffe_files(images: str | Path) -> dict[str, dict[str, list[Path]]]:
    """``{person: {code: [paths by instance]}}`` of the ``*.tiff`` in a JAFFE ``images`` folder.

    Examples
    --------
    >>> jaffe_files("/nonexistent")
    {}
    """
    out: dict[str, dict[str, list[Path]]] = {}
    for p in sorted(Path(images).glob("*.tiff")):
        parts = p.name.split(".")
        if len(parts) >= 3 and len(parts[1]) >= 3:
            out.setdefault(parts[0], {}).setdefault(parts[1][:2], []).append(p)
    for d in out.values():
        for k in d:
            d[k].sort(key=lambda q: (q.name.split(".")[1], q.name))
    return out
