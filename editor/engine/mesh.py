"""The standard mesh: topology (fixed for every face) loaded from ``editor/data/mesh.json``.

Only coordinates change from face to face; vertex indices, triangles, regions, feature-point
tags and the eye/mouth openings (holes, no triangles inside) are the same for every face.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np

from editor.resources import MESH

from .meshdef import crossing_pairs


@dataclass(frozen=True, eq=False)
class StandardMesh:
    """Topology of the standard face mesh.

    Attributes
    ----------
    names : tuple of str
        Vertex names (V,), e.g. ``"lipi_u4"``.
    regions : (V,) array of str
        Region of each vertex (``eye_contour``, ``mouth``, ..., ``margin``, ``border``).
    fdp : dict str -> int
        MPEG-4 feature point id -> vertex index (``"2.1" -> 123``).
    triangles : (T, 3) int32
        Vertex indices, oriented so that the signed area (SPEC eq. 3) is positive.
    holes : dict str -> (n,) int32
        Ordered vertex loops of the openings ``eye_l``, ``eye_r``, ``mouth``.
    pairs : (P, 2) int32
        (upper, lower) vertex pairs that may meet but never cross (inner lips, eyelids).
    template : (V, 2) float32
        Vertex positions on the template face (inter-ocular distance 100).

    Examples
    --------
    >>> from editor.core import standard_mesh
    >>> mesh = standard_mesh()
    >>> mesh.n_vertices, mesh.triangles.shape, len(mesh.edges())
    (285, (514, 3), 801)
    >>> mesh.names[mesh.fdp["2.1"]], mesh.index("contour_16")  # the chin
    ('contour_16', 135)
    >>> sorted(mesh.holes)
    ['eye_l', 'eye_r', 'mouth']
    """

    names: tuple[str, ...]
    regions: np.ndarray
    fdp: dict[str, int]
    triangles: np.ndarray
    holes: dict[str, np.ndarray]
    pairs: np.ndarray
    template: np.ndarray

    @property
    def n_vertices(self) -> int:
        """Number of vertices V."""
        return len(self.names)

    def index(self, name: str) -> int:
        """The index of the vertex called ``name`` (KeyError if there is none)."""
        return self._index[name]

    @cached_property
    def _index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.names)}

    def edges(self) -> np.ndarray:
        """Unique undirected edges (E, 2)."""
        e = self.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        return np.unique(np.sort(e, 1), axis=0)


@lru_cache(maxsize=1)
def standard_mesh(path: str | None = None) -> StandardMesh:
    """The standard face mesh (``editor/data/mesh.json``; loaded once, cached).

    Parameters
    ----------
    path : str, optional
        Another mesh file of the same format (tests, tools); default the shipped one.

    Returns
    -------
    StandardMesh

    Raises
    ------
    ValueError
        If the file is not a version-1 FAP Studio mesh.

    Examples
    --------
    >>> from editor.core import standard_mesh
    >>> standard_mesh() is standard_mesh()
    True
    >>> standard_mesh().regions[:3].tolist()
    ['eyebrow', 'eyebrow', 'eyebrow']
    """
    p = Path(path) if path else MESH
    d = json.loads(p.read_text())
    if d.get("format") != "fap-studio-mesh" or d.get("version") != 1:
        raise ValueError(f"{p}: not a version-1 FAP Studio mesh file")
    names = tuple(v["name"] for v in d["vertices"])
    idx = {n: i for i, n in enumerate(names)}
    pairs = np.array([[idx[a], idx[b]] for a, b in crossing_pairs()], np.int32)
    return StandardMesh(
        names=names,
        regions=np.array([v["region"] for v in d["vertices"]]),
        fdp={v["fdp"]: i for i, v in enumerate(d["vertices"]) if "fdp" in v},
        triangles=np.asarray(d["triangles"], np.int32),
        holes={k: np.array([idx[n] for n in v], np.int32) for k, v in d["holes"].items()},
        pairs=pairs,
        template=np.asarray([v["template"] for v in d["vertices"]], np.float32),
    )


def signed_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Twice the signed area of each triangle (SPEC eq. 3), batched.

    Positive for the mesh's own orientation; zero or negative marks a fold (a triangle turned
    over), which the deformation guards against.

    Parameters
    ----------
    vertices : numpy.ndarray
        (V, 2) or (B, V, 2) vertex positions (x, y), y down.
    triangles : numpy.ndarray
        (T, 3) vertex indices.

    Returns
    -------
    numpy.ndarray
        (T,) or (B, T).

    Examples
    --------
    >>> import numpy as np
    >>> from editor.core import signed_areas, standard_mesh
    >>> mesh = standard_mesh()
    >>> bool((signed_areas(mesh.template, mesh.triangles) > 0).all())
    True
    >>> flipped = mesh.template * [-1, 1]  # a mirror image turns every triangle over
    >>> bool((signed_areas(flipped, mesh.triangles) < 0).all())
    True
    >>> signed_areas(np.array([[0.0, 0], [2, 0], [0, 2]]), np.array([[0, 1, 2]])).tolist()
    [4.0]
    """
    a = vertices[..., triangles[:, 0], :]
    b = vertices[..., triangles[:, 1], :]
    c = vertices[..., triangles[:, 2], :]
    return ((c[..., 0] - a[..., 0]) * (c[..., 1] - b[..., 1])
            - (c[..., 1] - a[..., 1]) * (c[..., 0] - b[..., 0]))
