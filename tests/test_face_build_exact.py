"""What a face builds once (its deformation plans, ~17 while the photo's own expression is
estimated, and the first render's photo analysis) computed faster, with the same values bit for
bit as the straightforward code (kept here as the reference): the eq. 2 weights of all
rectangles at once, the face mask per coordinate, channel medians from histograms."""

from __future__ import annotations

import numpy as np

from editor.engine import influence
from editor.engine.fitting import box_medians, channel_median
from editor.engine.influence import Rect


def _axis_weight_reference(v, lo, hi, c0, plateau, parabolic):
    a, b = (c0, c0) if plateau is None else (min(plateau), max(plateau))
    a, b = max(a, lo + 1e-6), min(b, hi - 1e-6)
    w = np.zeros_like(v)
    left = (v > lo) & (v < a)
    right = (v > b) & (v < hi)
    mid = (v >= a) & (v <= b)
    if parabolic:
        w[left] = 1.0 - ((v[left] - a) / (lo - a)) ** 2
        w[right] = 1.0 - ((v[right] - b) / (hi - b)) ** 2
    else:
        w[left] = (v[left] - lo) / (a - lo)
        w[right] = (hi - v[right]) / (hi - b)
    w[mid] = 1.0
    return w


def _weights_reference(rect, p0, pts, sides, movable):
    x1, x2 = min(rect.x1, rect.x2), max(rect.x1, rect.x2)
    y1, y2 = min(rect.y1, rect.y2), max(rect.y1, rect.y2)
    eps = 1e-3
    x1, x2 = min(x1, p0[0] - eps), max(x2, p0[0] + eps)
    y1, y2 = min(y1, p0[1] - eps), max(y2, p0[1] + eps)
    wx = _axis_weight_reference(pts[:, 0], x1, x2, float(p0[0]), rect.px, rect.parabolic_x)
    wy = _axis_weight_reference(pts[:, 1], y1, y2, float(p0[1]), rect.py, False)
    w = wx * wy * movable
    if rect.side is not None:
        w = w * ~sides[influence._opposite(rect.side)]
    return w


def _inside_distance_reference(poly, pts):
    a = poly
    b = np.roll(poly, -1, axis=0)
    ab = b - a
    ap = pts[:, None, :] - a[None]
    t = np.clip((ap * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12)[None], 0.0, 1.0)
    d = np.linalg.norm(ap - t[..., None] * ab[None], axis=-1).min(1)
    py, px = pts[:, 1:2], pts[:, 0:1]
    ay, by, ax, bx = a[None, :, 1], b[None, :, 1], a[None, :, 0], b[None, :, 0]
    spans = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = ax + (py - ay) * (bx - ax) / (by - ay)
    inside = (spans & (px < xc)).sum(1) % 2 == 1
    return np.where(inside, d, -d)


def _random_rect(rng):
    c = rng.uniform(-50, 50, 4)
    px = None if rng.random() < 0.5 else tuple(rng.uniform(-60, 60, 2))
    py = None if rng.random() < 0.5 else tuple(rng.uniform(-60, 60, 2))
    side = rng.choice([None, "mouth_up", "mouth_low", "eye_l_up", "eye_r_low"])
    return Rect(*c, px=px, py=py, parabolic_x=bool(rng.random() < 0.3), side=side)


def test_weights_many_is_weights_one_by_one():
    rng = np.random.default_rng(15)
    for trial in range(300):
        n = int(rng.integers(1, 80))
        pts = rng.uniform(-70, 70, (n, 2))
        if trial % 4 == 0:  # points exactly on the rectangles' sides and plateaus
            pts = np.round(pts)
        sides = {k: rng.random(n) < 0.3 for k in ("mouth_up", "mouth_low", "eye_l_up",
                                                    "eye_l_low", "eye_r_up", "eye_r_low")}
        movable = rng.random(n) < 0.8
        rects = [_random_rect(rng) for _ in range(int(rng.integers(1, 12)))]
        if trial % 4 == 0:
            rects = [Rect(*np.round([r.x1, r.x2, r.y1, r.y2]), px=r.px, py=r.py,
                          parabolic_x=r.parabolic_x, side=r.side) for r in rects]
        p0 = rng.uniform(-40, 40, (len(rects), 2))
        got = influence.weights_many(rects, p0, pts, sides, movable)
        for i, r in enumerate(rects):
            ref = _weights_reference(r, p0[i], pts, sides, movable)
            assert np.array_equal(got[i], ref), (trial, i)
            assert np.array_equal(influence.weights(r, p0[i], pts, sides, movable), ref)


def test_weights_many_plateau_beyond_the_rectangle():
    # a plateau past the rectangle's side: the left and right ramps overlap just inside that
    # side (the right one wins, as it did)
    pts = np.stack([np.linspace(-1.0, 1.0, 2001), np.zeros(2001)], 1)
    pts[:, 0] = np.where(np.abs(pts[:, 0] - 0.5) < 1e-6, 0.5 - 5e-7, pts[:, 0])
    rects = [Rect(-1.0, -1.0, 0.5, 1.0, px=(0.8, 0.9)), Rect(-1.0, -1.0, 0.5, 1.0, px=(-2, -1.5))]
    sides = {k: np.zeros(len(pts), bool) for k in ("mouth_up", "mouth_low")}
    p0 = np.array([[0.0, 0.0], [0.0, 0.0]])
    got = influence.weights_many(rects, p0, pts, sides, np.ones(len(pts), bool))
    for i, r in enumerate(rects):
        ref = _weights_reference(r, p0[i], pts, sides, np.ones(len(pts), bool))
        assert np.array_equal(got[i], ref), i


def test_inside_distance_is_the_vector_form():
    rng = np.random.default_rng(16)
    for trial in range(200):
        s = int(rng.integers(3, 50))
        ang = np.sort(rng.uniform(0, 2 * np.pi, s))
        poly = np.stack([np.cos(ang), np.sin(ang)], 1) * rng.uniform(10, 60, (s, 1))
        pts = rng.uniform(-70, 70, (int(rng.integers(1, 300)), 2))
        if trial % 3 == 0:
            poly, pts = np.round(poly), np.round(pts)
            pts[: min(len(pts), s)] = poly[: min(len(pts), s)]  # on the outline
        assert np.array_equal(influence.inside_distance(poly, pts),
                              _inside_distance_reference(poly, pts)), trial


def test_sample_plan_weights_match_the_reference(sample_face):
    from editor.engine.deform import EXTRA_POINTS, _topology

    face = sample_face
    plan = face.plan
    topo = _topology(face.mesh)
    P = face.frame.to_frame(plan.neutral.astype(np.float64))
    byname = {n: P[i] for i, n in enumerate(topo.names)}
    iod = float(np.linalg.norm(byname["eye_l_u3"] - byname["eye_r_u3"]))
    rects = influence.rectangles(byname, iod)
    fdp_pos = {k: P[i] for k, i in face.mesh.fdp.items()}
    V = plan.n_vertices
    fdp_pos.update({k: P[V + i] for i, k in enumerate(EXTRA_POINTS)})
    keys = [k for k in rects if k in fdp_pos]
    got = influence.weights_many([rects[k] for k in keys], np.array([fdp_pos[k] for k in keys]),
                                 P, topo.sides, topo.movable_lin)
    for i, k in enumerate(keys):
        ref = _weights_reference(rects[k], fdp_pos[k], P, topo.sides, topo.movable_lin)
        assert np.array_equal(got[i], ref), k
        assert ref.any(), k  # each rectangle moves something
    poly = influence.face_polygon(byname)
    assert np.array_equal(influence.inside_distance(poly, P),
                          _inside_distance_reference(poly, P))


def test_channel_median_is_np_median():
    rng = np.random.default_rng(17)
    hist_path = 0
    for trial in range(400):
        # (small boxes take np.median itself, from 1024 pixels the histograms)
        h, w = int(rng.integers(1, 90)), int(rng.integers(1, 90))
        hi = int(rng.choice([2, 5, 256]))  # few levels: many ties
        img = rng.integers(0, hi, (h, w, 3), dtype=np.uint8)
        if trial % 2:
            big = rng.integers(0, 256, (h + 5, w + 7, 3), dtype=np.uint8)
            big[2:2 + h, 3:3 + w] = img
            img = big[2:2 + h, 3:3 + w]  # a view of a larger photo, as the callers pass
        mask = None if trial % 3 == 0 else (rng.random((h, w)) < rng.random()).astype(np.uint8)
        if mask is not None and not mask.any():
            mask[0, 0] = 1
        ref = np.median(img.reshape(-1, 3) if mask is None else img[mask > 0], axis=0)
        got = channel_median(img, mask)
        assert got.dtype == ref.dtype and np.array_equal(got, ref), trial
        n = h * w if mask is None else int(mask.sum())
        hist_path += n >= 1024
    assert hist_path > 50


def test_box_medians_are_np_medians():
    rng = np.random.default_rng(23)
    for trial in range(200):
        h, w = (int(x) for x in rng.integers(1, 120, 2))
        hi = int(rng.choice([2, 5, 256]))  # few levels: many ties
        img = rng.integers(0, hi, (h, w, 3), dtype=np.uint8)
        boxes = []
        for _ in range(int(rng.integers(1, 25))):
            x0, y0 = int(rng.integers(0, w)), int(rng.integers(0, h))
            boxes.append((x0, y0, int(rng.integers(x0 + 1, w + 1)),
                          int(rng.integers(y0 + 1, h + 1))))
        ref = np.array([np.median(img[y0:y1, x0:x1].reshape(-1, 3), axis=0)
                        for x0, y0, x1, y1 in boxes])
        got = box_medians(img, boxes)
        assert got.dtype == ref.dtype and np.array_equal(got, ref), trial

def test_landmark_jacobian_is_one_product_per_fap(sample_face):
    from editor.engine.deform import LIP_PAIRS
    from editor.engine.fap_model import FapEstimator, landmark_jacobian
    from editor.engine.laplacian import landmark_map

    f = sample_face
    A = landmark_map(f.vertices, f.triangles, f.mesh.names,
                     np.asarray(f.landmarks.points, np.float64))
    V = f.plan.n_vertices
    basis = f.plan.basis.astype(np.float64)[:, :V]
    ref = np.stack([(A @ basis[k]).ravel() for k in range(68)], 1)
    assert np.array_equal(landmark_jacobian(f, A), ref) and np.abs(ref).max() > 0
    pb = f.plan.pair_basis.reshape(len(LIP_PAIRS), -1, 2)[:, :V]
    ref_p = np.stack([(A @ pb[k]).ravel() for k in range(len(LIP_PAIRS))], 1)
    assert np.array_equal(FapEstimator(f).P, ref_p) and np.abs(ref_p).max() > 0


def _white_plate_reference(patch, opening, rho, r_fill, radius):
    """gaze._white_plate as it was: the fill made and blurred over the whole patch."""
    import cv2

    from editor.engine.gaze import _row_interp, _telea

    outside_iris = rho >= r_fill
    disc = opening & ~outside_iris
    out = patch.astype(np.float32)
    if disc.any():
        tel = _telea(patch, disc, radius)
        d_lid = cv2.distanceTransform(opening.astype(np.uint8), cv2.DIST_L2, 3)
        known = opening & outside_iris & (d_lid > 1.0)  # the white, clear of the lash line
        rows, wrow = _row_interp(tel, out, known, disc)
        wv = (np.clip((d_lid - 0.5) / 2.0, 0.0, 1.0) * wrow)[..., None]
        fill = wv * rows + (1.0 - wv) * tel
        fill = cv2.GaussianBlur(fill, (0, 0), max(0.6, 0.25 * radius))
        w = (np.clip(r_fill - rho, 0.0, 1.0) * opening)[..., None].astype(np.float32)
        out = w * fill + (1.0 - w) * out
    # the lid margin (the opening's outer pixel and a half) is lid, lashes and their shadow:
    # it stays with the lid, so the eyeball's white there continues the nearest white inside
    # (else a rotated eyeball carries the lash line into view: a dark stripe beside the iris)
    inner = opening & (cv2.distanceTransform(opening.astype(np.uint8), cv2.DIST_L2, 3) > 1.5)
    margin = opening & ~inner
    if inner.any() and margin.any():
        _, lab = cv2.distanceTransformWithLabels((~inner).astype(np.uint8), cv2.DIST_L2, 3,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
        iy, ix = np.nonzero(inner)  # labels number the zero pixels in this (row-major) order
        near = lab[margin] - 1
        out[margin] = out[iy[near], ix[near]]
    ph, pw = opening.shape
    full = np.flatnonzero(opening.any(0))
    if len(full):
        # each column above / below its opening repeats its first / last row inside, a column
        # without opening the nearest column with one (the smaller on a tie)
        top = np.argmax(opening, 0)
        bot = ph - 1 - np.argmax(opening[::-1], 0)
        src = full[np.abs(np.arange(pw)[:, None] - full[None, :]).argmin(1)]
        yy = np.arange(ph)[:, None]
        out = out[np.clip(yy, top[src][None, :], bot[src][None, :]), src[None, :]]
    return out


def test_white_plate_blurs_the_disc_box_only():
    import cv2

    from editor.engine.gaze import _white_plate

    rng = np.random.default_rng(18)
    for trial in range(24):
        r = float(rng.choice([3.0, 7.5, 12.0, 34.0]))
        h, w = int(rng.integers(int(3 * r), int(5 * r))), int(rng.integers(int(5 * r), int(8 * r)))
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        white = 200.0 - 0.15 * xx - 40.0 * np.exp(-yy / 25.0)
        patch = np.dstack([white, white * 0.95, white * 0.9]) + rng.normal(0, 6, (h, w, 3))
        patch = np.clip(patch, 0, 255).astype(np.uint8)
        # the iris anywhere, also against the patch's edges
        cx, cy = rng.uniform(0.2 * w, 0.8 * w), rng.uniform(0.0, h)
        rho = np.hypot(xx - cx, yy - cy).astype(np.float64)
        patch[rho < r] = (60, 40, 30)
        opening = np.zeros((h, w), np.uint8)
        cv2.ellipse(opening, (w // 2, h // 2), (int(0.45 * w), int(rng.uniform(0.2, 0.5) * h)),
                    0, 0, 360, 1, -1)
        opening = opening > 0
        r_fill = r + max(1.5, 0.3 * r)
        got = _white_plate(patch, opening, rho, r_fill, r)
        ref = _white_plate_reference(patch, opening, rho, r_fill, r)
        assert np.array_equal(got, ref), trial


def _ball_white_reference(plate, opening, r, band_up, band_low):
    """gaze._ball_white as it was: the shading computed over the whole patch."""
    import cv2

    from editor.engine.gaze import BALL_SHADE, _column_percentile

    ph, pw = opening.shape
    cols = np.flatnonzero(opening.any(0))
    out = plate.copy()
    if len(cols) == 0:
        return out
    top = np.argmax(opening, 0)
    bot = ph - 1 - np.argmax(opening[::-1], 0)
    mid = 0.5 * (top + bot)
    ref_t = np.minimum(np.rint(top + band_up), np.floor(mid)).astype(np.int64)
    ref_b = np.maximum(np.rint(bot - band_low), np.ceil(mid)).astype(np.int64)
    ref_t, ref_b = np.clip(ref_t, 0, ph - 1), np.clip(ref_b, 0, ph - 1)
    jj = np.arange(pw)

    # the white of each column: its brighter part between the lids' shadow bands (the plate
    # has no iris), as bright as the sclera near the eye's middle
    yy = np.arange(ph, dtype=np.float32)[:, None]
    mid_rows = opening & (yy >= ref_t[None, :]) & (yy <= ref_b[None, :])
    mid_rows |= opening & ~mid_rows.any(0)[None, :]
    lum = plate @ np.array([0.299, 0.587, 0.114], np.float32)
    thr = _column_percentile(lum[:, cols], mid_rows[:, cols], 80)
    sel = np.zeros_like(opening)
    sel[:, cols] = mid_rows[:, cols] & (lum[:, cols] >= thr[None, :] - 1e-3)
    cnt = sel.sum(0)
    ok = cnt > 0
    ref = np.zeros((pw, 3), np.float32)
    ref[ok] = (plate * sel[..., None]).sum(0)[ok] / cnt[ok, None]
    for ch in range(3):
        ref[:, ch] = np.interp(jj, jj[ok], ref[ok, ch])
    ref = cv2.GaussianBlur(ref[None], (0, 0), max(0.8, 0.3 * r))[0]
    c_t, c_b = ref, ref
    near = cols[np.abs(jj[:, None] - cols[None, :]).argmin(1)]
    ref_t, ref_b = ref_t[near], ref_b[near]
    d_t = np.maximum(ref_t[None, :] - yy, 0.0)
    d_b = np.maximum(yy - ref_b[None, :], 0.0)
    shade_t = (1.0 - BALL_SHADE * (1.0 - np.exp(-d_t / max(r, 1.0))))[..., None]
    shade_b = (1.0 - BALL_SHADE * (1.0 - np.exp(-d_b / max(r, 1.0))))[..., None]
    # (the float64 colours written only where they go, rounded to float32 as before)
    for side, c, shade in ((yy < ref_t[None, :], c_t, shade_t),
                           (yy > ref_b[None, :], c_b, shade_b)):
        iy, ix = np.nonzero(side)
        out[iy, ix] = c[ix] * shade[iy, ix]
    return out


def test_ball_white_shades_where_it_writes():
    import cv2

    from editor.engine.gaze import _ball_white

    rng = np.random.default_rng(19)
    for trial in range(40):
        h, w = int(rng.integers(8, 120)), int(rng.integers(8, 200))
        plate = rng.uniform(120, 240, (h, w, 3)).astype(np.float32)
        opening = np.zeros((h, w), np.uint8)
        cv2.ellipse(opening, (w // 2, h // 2), (int(rng.uniform(0.2, 0.5) * w),
                                                int(rng.uniform(0.1, 0.5) * h)), 0, 0, 360, 1, -1)
        if trial % 5 == 0:
            opening[:, : w // 3] = 0  # columns without opening
        r = float(rng.uniform(2.0, 35.0))
        args = (plate, opening > 0, r, max(2.5, 0.5 * r), max(1.5, 0.25 * r))
        assert np.array_equal(_ball_white(*args), _ball_white_reference(*args)), trial
