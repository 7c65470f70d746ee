"""A large face in a large photo (issue 15) warps through a backward map interpolated between
nodes :data:`~editor.engine.warp.MAP_STEP` px apart where it bends gently, exact elsewhere
(:func:`~editor.engine.warp._maps_coarse`): the map stays within a stated distance of the
exact piecewise-affine one, the openings and their masks exactly; faces and photos up to
1080p keep the exact map (their renders do not change)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import map_error

import editor.engine.warp as warp_mod
from editor.core import FAPS, Face, apply_preset
from editor.engine.imageio import load_image
from editor.engine.jawband import jaw_map
from editor.engine.landmarks import detect_landmarks
from editor.engine.warp import WarpPlan, map_step, warp
from editor.resources import SAMPLE_FACE

#: tolerance of the interpolated backward map against the exact one, pixels
MAP_MAX_PX = 0.5
MAP_MEAN_PX = 0.003
#: share of the box's pixels whose map is off by more than a quarter of a pixel
MAP_OVER_QUARTER = 1e-4
#: the warped image against the exact warp's (grey levels): max and mean absolute difference
IMG_MAX = 4
IMG_MEAN = 0.01

EXPRESSIONS = {
    "bench": {"open_jaw": 500, "raise_l_cornerlip_o": 250, "raise_r_cornerlip_o": 250,
              "raise_l_cornerlip": 250, "raise_r_cornerlip": 250, 31: 200, 32: 200, 33: 200,
              34: 200, 35: 150, 36: 150, 19: -100, 20: -100},
    "surprise_150": ("surprise", 1.5),
    "sadness": ("sadness", 1.0),
    "viseme_pbm": ("viseme_pbm", 1.0),
}


def _vector(spec) -> np.ndarray:
    if isinstance(spec, tuple):
        return apply_preset(*spec)
    return FAPS.clamp(FAPS.vector(spec))


@pytest.fixture(scope="module")
def large_face() -> Face:
    """The sample upscaled (x 6.2: about 225 px between the eyes), its
    centre in a 2560 x 1440 frame (padded by reflection)."""
    img = load_image(SAMPLE_FACE)
    k = 6.2
    cx, cy = (detect_landmarks(img).points.mean(0) * k).astype(int)  # the face's centre
    big = cv2.resize(img, None, fx=k, fy=k, interpolation=cv2.INTER_CUBIC)
    pad = 1400
    big = cv2.copyMakeBorder(big, pad, pad, pad, pad, cv2.BORDER_REFLECT_101)
    cx, cy = cx + pad, cy + pad
    return Face.from_image(np.ascontiguousarray(big[cy - 720:cy + 720, cx - 1280:cx + 1280]))


def _exact(face: Face) -> WarpPlan:
    return WarpPlan(face.image, face.vertices, face.mesh.triangles, face.mesh.holes,
                    band=face.mesh.regions == "margin")


def test_map_step_by_face_and_photo_size(large_face, sample_face):
    assert large_face.interocular >= warp_mod.COARSE_IOD
    assert large_face.warp_plan.map_step == warp_mod.MAP_STEP > 1
    assert sample_face.warp_plan.map_step == 1
    # up to 1080p the map is exact, however large the face
    assert map_step(400.0, (1080, 1920, 3)) == 1
    assert map_step(150.0, (2160, 3840, 3)) == 1
    assert map_step(400.0, (2160, 3840, 3)) == warp_mod.MAP_STEP


@pytest.mark.parametrize("name", sorted(EXPRESSIONS))
def test_coarse_map_matches_exact_within_tolerance(large_face, name):
    face = large_face
    vec = _vector(EXPRESSIONS[name])
    v = face.deform(vec)
    tf = face.layer_transforms(v)
    got = warp(face.warp_plan, v, tf, cavity=False, hook=jaw_map(face, v))
    # (the exact map of the same moved vertices: a large face leaves those that move by at
    # most MAP_TOL still; against every vertex's motion, the picture below)
    exact = warp(_exact(face), v, tf, cavity=False, hook=jaw_map(face, v), tol=warp_mod.MAP_TOL)
    assert got.bbox == exact.bbox and got.bbox is not None
    err = map_error(got, exact)
    assert err.max() <= MAP_MAX_PX
    assert err.mean() <= MAP_MEAN_PX
    assert (err > 0.25).mean() <= MAP_OVER_QUARTER
    # the openings (where the map jumps to the eyeballs' and the mouth interior's) exactly
    assert np.array_equal(got.mouth_local, exact.mouth_local)
    assert np.array_equal(got.eyes_local, exact.eyes_local)
    assert got.mouth_local is not None and got.eyes_local is not None
    assert err[got.mouth_local | got.eyes_local].max() <= 1e-3
    # the picture: a few grey levels at most, outside the box the photo itself
    d = np.abs(got.image.astype(np.int16) - exact.image)
    assert d.max() <= IMG_MAX and d.mean() <= IMG_MEAN
    x0, y0, x1, y1 = got.bbox
    outside = np.ones(face.image.shape[:2], bool)
    outside[y0:y1, x0:x1] = False
    assert np.array_equal(got.image[outside], face.image[outside])
    # every vertex's motion warped exactly: the vertices left still move the photo by less
    # than MAP_TOL px, a grey level or two at most on a few pixels
    full = warp(_exact(face), v, tf, cavity=False, hook=jaw_map(face, v))
    d = np.abs(got.image.astype(np.int16) - full.image)
    assert d.max() <= IMG_MAX and d.mean() <= IMG_MEAN


def test_sharp_edges_need_the_exact_map(large_face, monkeypatch):
    """Interpolated across every edge (the squashed lips, sharp bends), the map would be off
    by many pixels: the tolerance above is what the exact edges buy."""
    face = large_face
    vec = _vector(EXPRESSIONS["sadness"])
    v = face.deform(vec)
    tf = face.layer_transforms(v)
    exact = warp(_exact(face), v, tf, cavity=False)
    monkeypatch.setattr(warp_mod, "MAP_KINK_PX", 1e9)
    monkeypatch.setattr(warp_mod, "MAP_KINK_NEAR_PX", 1e9)
    loose = warp(face.warp_plan, v, tf, cavity=False)
    err = map_error(loose, exact)
    assert err.max() > 4 * MAP_MAX_PX


def test_render_of_a_large_face_close_to_the_exact_render(large_face):
    face = large_face
    vec = _vector(EXPRESSIONS["bench"])
    got = face.render(vec)
    exact_face = face.with_vertices(face.vertices)
    exact_face.__dict__["warp_plan"] = _exact(exact_face)
    exact = exact_face.render(vec)
    d = np.abs(got.astype(np.int16) - exact)
    assert d.mean() <= IMG_MEAN
    assert (d > 8).mean() <= 1e-4


def test_jaw_hook_joins_the_map_on_its_nodes(large_face):
    """The jaw's hook gives its map on a grid of nodes (the coarse map takes it there instead
    of calling it pixel by pixel): within a small fraction of a pixel of its map evaluated at
    each node (the shift's fade interpolated from nodes twice as far apart, as the hook's
    pixels from its own grid), and exactly the node's own position where it has faded out."""
    from editor.engine.jawband import _band
    from editor.engine.warp import NodeHook

    face = large_face
    v = face.deform(_vector(EXPRESSIONS["bench"]))
    hook = jaw_map(face, v)
    assert isinstance(hook, NodeHook)
    x0, y0, x1, y1 = hook.box
    s = warp_mod.MAP_STEP
    nx, ny = (x1 - x0) // s, (y1 - y0) // s
    mx, my = hook.nodes(x0 + 0.25, y0 + 0.25, s, nx, ny)
    xs = (x0 + 0.25 + s * np.arange(nx)).astype(np.float32)
    ys = (y0 + 0.25 + s * np.arange(ny)).astype(np.float32)
    gx, gy = np.meshgrid(xs, ys)
    px, py = hook.points(gx.ravel(), gy.ravel())
    err = np.maximum(np.abs(mx.ravel() - px), np.abs(my.ravel() - py))
    assert err.max() <= 0.3 and err.mean() <= 0.01
    moved = (mx != gx) | (my != gy)
    assert moved.any() and not moved.all()  # (the neck below the fade maps to itself)
    assert len(_band(face).idx) > 0
