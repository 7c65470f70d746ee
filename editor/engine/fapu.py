"""Facial Animation Parameter Units measured on the neutral personalized mesh (SPEC §1.4).

Distances are axis-aligned differences in the roll-corrected face frame (so a tilted photo is
measured as if upright), in pixels. Convention: MPEG-4's, i.e. MNS0 and ENS0 are measured from
the subnasale 9.15 (not the nose tip 9.3 of the paper), so that .fap files made for other MPEG-4
players give the same motion here. The lip line (2.2) is taken as the mean of the inner upper and
lower lip middles, which is the lip line of a closed mouth and stays right for a parted one.
The eyelid distances are measured on the vertical through each iris centre and averaged over
both eyes.

One unit is the distance / 1024 (pixels per unit); AU = 1e-5 rad.
"""

from __future__ import annotations

import numpy as np

from .fitting import FaceFrame
from .mesh import StandardMesh


def _lid_y(frame_xy: np.ndarray, mesh: StandardMesh, s: str, lid: str, x: float) -> float:
    names = [f"eye_{s}_c0"] + [f"eye_{s}_{lid}{k}" for k in range(1, 6)] + [f"eye_{s}_c1"]
    pts = frame_xy[[mesh.index(n) for n in names]]
    order = np.argsort(pts[:, 0])
    return float(np.interp(x, pts[order, 0], pts[order, 1]))


def measure_fapu(vertices: np.ndarray, mesh: StandardMesh, frame: FaceFrame,
                 irises: np.ndarray) -> dict[str, float]:
    """FAPU in pixels per unit from the neutral mesh ``vertices`` (V, 2) and irises (2, 3)."""
    q = frame.to_frame(vertices)
    f = {k: q[i] for k, i in mesh.fdp.items()}
    iris_f = frame.to_frame(np.asarray(irises)[:, :2])
    lids = []
    for (s, ix) in (("r", 0), ("l", 1)):
        x = float(iris_f[ix, 0])
        lids.append((_lid_y(q, mesh, s, "u", x), _lid_y(q, mesh, s, "d", x)))
    lids_a = np.array(lids)
    lip_line = 0.5 * (f["2.2"][1] + f["2.3"][1])
    d = {
        "MNS": lip_line - f["9.15"][1],
        "MW": f["8.3"][0] - f["8.4"][0],
        "IRISD": float(np.mean(lids_a[:, 1] - lids_a[:, 0])),
        "ENS": f["9.15"][1] - float(np.mean(lids_a)),
        "ES": float(iris_f[1, 0] - iris_f[0, 0]),
    }
    out = {k: max(float(v), 1e-3) / 1024.0 for k, v in d.items()}
    out["AU"] = 1e-5
    return out
