"""Names, regions and MPEG-4 feature points of the standard mesh's vertices.

Shared by the build script (``scripts/build_mesh.py``) and the runtime loader. Face's own
left/right: ``_l`` = the subject's left = the image's right.
"""

from __future__ import annotations

#: Vertex name -> MPEG-4 feature point id.
FDP_OF_VERTEX: dict[str, str] = {
    "contour_16": "2.1", "lipi_u4": "2.2", "lipi_d4": "2.3", "lipi_c1": "2.4", "lipi_c0": "2.5",
    "lipi_u6": "2.6", "lipi_u2": "2.7", "lipi_d6": "2.8", "lipi_d2": "2.9", "jaw_2_4": "2.10",
    "contour_20": "2.11", "contour_12": "2.12", "contour_24": "2.13", "contour_8": "2.14",
    "eye_l_u3": "3.1", "eye_r_u3": "3.2", "eye_l_d3": "3.3", "eye_r_d3": "3.4",
    "eye_l_c1": "3.7", "eye_r_c1": "3.8", "eyering_l_d3": "3.9", "eyering_r_d3": "3.10",
    "eye_l_c0": "3.11", "eye_r_c0": "3.12", "eyering_l_u3": "3.13", "eyering_r_u3": "3.14",
    "brow_l_e0": "4.1", "brow_r_e1": "4.2", "brow_l_u3": "4.3", "brow_r_u3": "4.4",
    "brow_l_e1": "4.5", "brow_r_e0": "4.6",
    "cheek_l_4_2": "5.1", "cheek_r_4_2": "5.2", "cheek_l_2_2": "5.3", "cheek_r_2_2": "5.4",
    "lipo_u4": "8.1", "lipo_d4": "8.2", "lipo_c1": "8.3", "lipo_c0": "8.4", "lipo_u6": "8.5",
    "lipo_u2": "8.6", "lipo_d6": "8.7", "lipo_d2": "8.8", "lipo_u3": "8.9", "lipo_u5": "8.10",
    "nose_35": "9.1", "nose_31": "9.2", "nose_30": "9.3", "nose_32": "9.4", "nose_34": "9.5",
    "nose_side_r": "9.6", "nose_side_l": "9.7", "nose_29": "9.12", "nose_33": "9.15",
    "ear_l_top": "10.1", "ear_r_top": "10.2", "ear_l_back": "10.3", "ear_r_back": "10.4",
    "ear_l_lobe": "10.5", "ear_r_lobe": "10.6", "contour_27": "10.7", "contour_5": "10.8",
    "contour_32": "10.9", "contour_0": "10.10",
    "hair_6": "11.1", "hair_2": "11.2", "hair_10": "11.3",
}

#: Name prefix -> region (SPEC §1.2 regions, plus our ear, margin and border rings).
REGION_PREFIXES: tuple[tuple[str, str], ...] = (
    ("eyering_", "eye_contour"), ("eye_", "eye_contour"), ("brow_", "eyebrow"),
    ("nose", "nose"), ("ala_", "nose"), ("lip", "mouth"), ("contour_", "contour"),
    ("hair_", "forehead"), ("forehead_", "forehead"), ("glabella", "forehead"),
    ("cheek_", "cheek"), ("nlab_", "cheek"), ("mcorner_", "cheek"), ("temple_", "cheek"),
    ("phil_", "cheek"), ("jaw_", "jaw"), ("ear_", "ear"), ("margin_", "margin"),
    ("border_", "border"),
)


def region_of(name: str) -> str:
    for prefix, region in REGION_PREFIXES:
        if name.startswith(prefix):
            return region
    raise KeyError(name)


def eye_hole(s: str) -> list[str]:
    """Vertex names around the eye opening ``s`` ('l' or 'r'), in order."""
    return ([f"eye_{s}_c0"] + [f"eye_{s}_u{k}" for k in range(1, 6)] + [f"eye_{s}_c1"]
            + [f"eye_{s}_d{k}" for k in range(5, 0, -1)])


def mouth_hole() -> list[str]:
    """Vertex names around the mouth opening (the inner lip contour), in order."""
    return (["lipi_c0"] + [f"lipi_u{k}" for k in range(1, 8)] + ["lipi_c1"]
            + [f"lipi_d{k}" for k in range(7, 0, -1)])


#: Pairs (upper, lower) that may meet but never cross: inner lips and eyelids.
def crossing_pairs() -> list[tuple[str, str]]:
    pairs = [(f"lipi_u{k}", f"lipi_d{k}") for k in range(1, 8)]
    for s in "lr":
        pairs += [(f"eye_{s}_u{k}", f"eye_{s}_d{k}") for k in range(1, 6)]
    return pairs
