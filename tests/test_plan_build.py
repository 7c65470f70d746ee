"""The per-face plan build (the first render's photo analysis) computes vectorised what it
used to compute row by row, column by column or triangle by triangle: each vectorised helper
gives the same values, bit for bit, as the straightforward computation it replaces (kept here as
the reference), on random inputs and on the sample's mesh."""

from __future__ import annotations

import warnings

import cv2
import numpy as np
import pytest

from editor.engine import creases, fitting, gaze, layers, mouth


def _random_masks(rng, n, max_h=50, max_w=40):
    for trial in range(n):
        h, w = int(rng.integers(1, max_h)), int(rng.integers(1, max_w))
        yield trial, h, w, rng.random((h, w)) < rng.random()


def test_column_percentile_is_nanpercentile():
    rng = np.random.default_rng(5)
    for trial, h, w, valid in _random_masks(rng, 1500):
        dt = (np.float32, np.float64)[trial % 2]
        vals = (rng.random((h, w)) * rng.choice([1.0, 255.0, 1e4])).astype(dt)
        if trial % 3 == 0:
            vals = np.round(vals)  # ties
        if trial % 5:
            valid[rng.integers(0, h)] = True  # (else some columns have no valid value)
        q = (80, 20, 25, 90, 50)[trial % 5]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns
            ref = np.nanpercentile(np.where(valid, vals, np.nan), q, axis=0)
        got = gaze._column_percentile(vals, valid, q)
        assert got.dtype == ref.dtype
        assert np.array_equal(got, ref, equal_nan=True), (trial, q)


def _row_interp_reference(tel, out, known, disc):
    rows = tel.copy()
    wrow = np.zeros(disc.shape, np.float32)
    cols = np.arange(disc.shape[1])
    for i in np.flatnonzero(disc.any(1)):
        k = np.flatnonzero(known[i])
        f = np.flatnonzero(disc[i])
        if len(k) == 0 or k.min() > f.min() or k.max() < f.max():
            continue
        for ch in range(3):
            rows[i, f, ch] = np.interp(cols[f], k, out[i, k, ch])
        wrow[i, f] = 1.0
    return rows, wrow


def test_row_interp_is_np_interp_per_row():
    rng = np.random.default_rng(6)
    for trial, h, w, m in _random_masks(rng, 400):
        disc = m & (rng.random((h, w)) < 0.5)
        known = m & ~disc  # disjoint, as the white and the iris disc
        tel = (rng.random((h, w, 3)) * 255).astype(np.float32)
        out = (rng.random((h, w, 3)) * 255).astype(np.float32)
        rows, wrow = gaze._row_interp(tel, out, known, disc)
        ref_rows, ref_w = _row_interp_reference(tel, out, known, disc)
        assert np.array_equal(rows, ref_rows) and np.array_equal(wrow, ref_w), trial


def _teeth_columns_reference(binary, bright):
    ph, pw = binary.shape
    split = np.full(pw, np.nan)
    weight = np.zeros(pw)
    first = np.full(pw, -1)
    gap = np.zeros(pw, bool)
    col_top = np.zeros(pw, np.int64)
    sliver = np.zeros(pw, bool)
    for j in np.flatnonzero(binary.any(0)):
        rows = np.flatnonzero(binary[:, j])
        top, bot = int(rows[0]), int(rows[-1])
        weight[j] = 1.0
        sliver[j] = bot - top < 2
        col_top[j] = top
        b = bright[top:bot + 1, j].copy()
        if b.any():
            b[1:-1] |= b[:-2] & b[2:]
            f = int(np.argmax(b))
            e = f
            while e + 1 < len(b) and b[e + 1]:
                e += 1
            split[j] = top + e + 0.5
            gap[j] = top + e + 1 <= bot
            if f <= 1:
                first[j] = top + f
        else:
            split[j] = 0.5 * (top + bot)
    return split, weight, first, gap, col_top, sliver


def test_teeth_columns_is_the_column_loop():
    rng = np.random.default_rng(7)
    for trial, h, w, binary in _random_masks(rng, 600, 30, 30):
        if trial % 2:  # (openings as they are: one run per column, a few gaps)
            top = rng.integers(0, h, w)
            binary = (np.arange(h)[:, None] >= top) & (np.arange(h)[:, None] <= top
                                                        + rng.integers(0, h, w))
            binary &= rng.random((h, w)) < 0.95
        bright = binary & (rng.random((h, w)) < rng.random())
        got = layers._teeth_columns(binary, bright)
        ref = _teeth_columns_reference(binary, bright)
        for g, r in zip(got, ref, strict=True):
            assert g.dtype == r.dtype and np.array_equal(g, r, equal_nan=True), trial


def test_locate_is_the_test_against_every_triangle(sample_face):
    V = sample_face.vertices.astype(np.float64)
    tris = sample_face.mesh.triangles
    a, b, c = (V[tris[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    det = np.where(np.abs(det) < 1e-12, 1e-12, det)
    rng = np.random.default_rng(8)
    lo, hi = V.min(0), V.max(0)
    sets = [lo - 20 + rng.random((800, 2)) * (hi - lo + 40),  # inside and outside the mesh
            V[rng.integers(0, len(V), 400)],  # on vertices
            0.5 * (V[tris[:, 0]] + V[tris[:, 1]]),  # on edges
            V[rng.integers(0, len(V), 400)] + rng.normal(0, 0.3, (400, 2))]
    for pts in sets:
        ti, bary = creases._locate(pts, V, tris)
        ref_t, ref_b = creases._locate_all(pts, a, e1, e2, det)
        assert np.array_equal(ti, ref_t.astype(np.int32))
        assert np.array_equal(bary, ref_b)


def test_is_grey():
    img = np.full((60, 80, 3), 120, np.uint8)
    img[..., 0] = np.arange(80, dtype=np.uint8)[None, :]
    img[..., 1] = img[..., 0]
    img[..., 2] = img[..., 0]
    assert fitting.is_grey(img)
    img[3, 5, 2] += 1  # one pixel off the sparse sample's grid
    assert not fitting.is_grey(img)
    img[3, 5, 2] -= 1
    img[7, 14, 1] += 1  # one on it
    assert not fitting.is_grey(img)


@pytest.mark.parametrize("name", mouth.NAMES)
def test_texture_tint_and_mean_are_the_pixel_formulas(name):
    rgba = mouth.load_textures()[name]
    c = rgba[..., :3]
    for sat, gain in ((0.0, (1.0, 1.0, 1.0)), (0.37, (1.3, 0.9, 0.7)), (1.0, (2.5, 2.4, 2.6))):
        g = np.array(gain, np.float32)
        lum = mouth._lum(c)[..., None]
        t = np.clip((lum + sat * (c - lum)) * g[None, None, :], 0, 255) * rgba[..., 3:4]
        ref = np.dstack([t, rgba[..., 3:4]]).astype(np.float32)
        assert np.array_equal(mouth._tint(name, sat, g), ref)
        opaque = rgba[..., 3] > 0.9
        if name.endswith("_teeth"):  # the crowns: the gum band is not the teeth's colour
            opaque &= c[..., 0] - c[..., 1] < 0.15 * 255.0
        co = c[opaque]
        lo = mouth._lum(co)[:, None]
        ref_mean = (lo + sat * (co - lo)).mean(0, dtype=np.float64)
        got = mouth._opaque_mean(name, sat)  # (float64 means of lum and chroma, combined)
        assert got.dtype == np.float32
        assert np.abs(got - ref_mean).max() < 1e-3
        # a face's copy: resized, then tinted (the same values, to float rounding, whether
        # nothing is clipped or the gain clips and the full texture is tinted)
        for size in ((34, 10), (70, 20), (250, 80), (900, 300)):
            # (the teeth's gaps kept at a face's size: one darkening factor per texture pixel)
            want = cv2.resize(mouth._with_gaps(mouth._tint(name, sat, g), name, size), size,
                              interpolation=cv2.INTER_AREA)
            small = mouth._tinted_at(name, sat, g, size)
            assert small.dtype == np.float32 and small.shape == want.shape
            assert np.abs(small - want).max() < 1e-3


def test_fold_normals_are_the_gradients_turned():
    # every line's normals, computed in one pass over all of them, are its own gradient's
    rng = np.random.default_rng(9)
    lines, refs = [], []
    for n in (2, 3, 10, 28, 40):
        pts = rng.normal(0, 50, (n, 2)).cumsum(0)
        pts[n // 2] = pts[n // 2 - 1]  # a repeated point: a zero tangent there at most
        tang = np.gradient(pts, axis=0)
        tang /= np.maximum(np.linalg.norm(tang, axis=1, keepdims=True), 1e-9)
        lines.append(pts)
        refs.append(np.stack([-tang[:, 1], tang[:, 0]], 1))
    for nrm, ref in zip(creases._lines_normals(lines), refs, strict=True):
        assert np.array_equal(nrm, ref)


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return (a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
            and np.array_equal(np.signbit(a), np.signbit(b)))


def test_median_and_percentile_are_numpys():
    rng = np.random.default_rng(11)
    for trial in range(3000):
        n = int(rng.integers(1, 300))
        kind = trial % 5
        if kind == 0:
            a = (rng.random(n) * 255).astype(np.float32)
        elif kind == 1:
            a = rng.normal(size=n)
        elif kind == 2:
            a = rng.integers(0, 8, n).astype(np.float32)  # ties
        elif kind == 3:
            a = rng.integers(0, 256, (n, 3)).astype(np.uint8)
        else:
            a = ((rng.random((n, 3)) * 3).round(1) - 1.5).astype(np.float32)
        if a.ndim == 2:
            assert _same(fitting.median(a, axis=0), np.median(a, axis=0)), trial
            a = a[:, 0]
        q = float(rng.choice([10, 20, 25, 50, 80, 90, 0, 100, rng.random() * 100]))
        assert _same(fitting.median(a), np.median(a)), trial
        assert _same(fitting.percentile(a, q), np.percentile(a, q)), (trial, q)
        assert _same(fitting.percentile(a, int(q)), np.percentile(a, int(q))), (trial, q)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        nan = np.array([1.0, np.nan, 2.0], np.float32)
        assert _same(fitting.median(nan), np.median(nan))
        assert _same(fitting.percentile(nan, 30.0), np.percentile(nan, 30.0))


def test_unmasked_median_abs_is_the_median_of_the_unmasked():
    from editor.engine import lipseal

    rng = np.random.default_rng(11)
    for trial, h, w, masked in _random_masks(rng, 400):
        hp = (rng.normal(0.0, 3.0, (h, w, 3)) * (1.0, 10.0)[trial % 2]).astype(np.float32)
        if trial % 3 == 0:
            hp = np.round(hp)  # ties and zeros
        mask = masked.astype(np.uint8) * 255
        free = ~masked
        if not free.any():
            continue
        ref = float(np.median(np.abs(hp[free])))
        assert lipseal._unmasked_median_abs(hp, mask) == ref, trial


def test_median_binned_is_numpys():
    """fitting.median_binned: np.median's value (a zero's sign aside) on float arrays large
    enough for its histogram (ties, skewed values, constant arrays, odd and even counts), and
    np.median's itself below that size."""
    rng = np.random.default_rng(11)
    for trial in range(300):
        n = int(rng.integers(1, 60_000))
        dt = (np.float32, np.float64)[trial % 2]
        a = rng.standard_normal(n) * rng.choice([1e-3, 1.0, 300.0])
        if trial % 3 == 0:
            a = np.round(a)  # ties
        if trial % 4 == 0:
            a = np.exp(np.clip(a, -50, 50))  # skewed: most values in a few bins
        if trial % 25 == 0:
            a[:] = a[0]  # constant
        a = a.astype(dt)
        got, ref = fitting.median_binned(a), float(np.median(a))
        assert got == ref, (trial, n, got, ref)


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
def test_close_is_the_elliptic_closing(dtype):
    """creases._close: OpenCV's closing by the elliptic kernel, bit for bit, at every radius
    (through the chain of lines from creases._CLOSE_STEPS_MIN), on boxes smaller and larger
    than the kernel, one and three channels."""
    rng = np.random.default_rng(3)
    for r in range(1, 26):
        for shape in ((3, 5), (40, 31), (90, 118, 3), (2 * r + 7, 17)):
            img = cv2.GaussianBlur(rng.uniform(0, 255, shape).astype(np.float32), (0, 0), 1.5)
            img = img.astype(dtype)
            ref = cv2.morphologyEx(img, cv2.MORPH_CLOSE, creases._ellipse(r))
            assert np.array_equal(creases._close(img, r), ref), (r, shape)


def test_spread3_is_the_broadcast():
    rng = np.random.default_rng(9)
    for trial, h, w, mask in _random_masks(rng, 60):
        for a in (mask.view(np.uint8), rng.random((h, w)).astype(np.float32), rng.random((h, w)),
                  rng.random((h + 3, w + 2))[1:1 + h, 2:2 + w]):  # (the last a view)
            got = gaze.spread3(a)
            assert got.dtype == a.dtype, trial
            assert np.array_equal(got, np.repeat(a[..., None], 3, axis=2)), trial


def test_zero_alpha_is_the_channels_written_into_zeros():
    rng = np.random.default_rng(11)
    for h, w in ((1, 1), (7, 3), (65, 120)):
        rgb = (rng.random((h, w, 3)) * 510 - 255).astype(np.float32)
        ref = np.zeros((h, w, 4), np.float32)
        ref[..., :3] = rgb
        got = gaze.zero_alpha(rgb)
        assert got.dtype == np.float32 and np.array_equal(got, ref)
        assert not np.signbit(got[..., 3]).any()


def test_neutral_vertices_are_the_zero_deformation(sample_face):
    # (creases._fast reads the neutral mesh as face.neutral_vertices)
    assert sample_face.has_expression
    got = sample_face.deform(None)
    assert got.dtype == sample_face.neutral_vertices.dtype
    assert np.array_equal(got, sample_face.neutral_vertices)


def test_running_sum_of_planes_is_the_first_axis_mean():
    # (MouthPlan.build's gum colour: the mean of (n, 3) pixels over the first axis, from
    # (3, n) planes as a running sum)
    rng = np.random.default_rng(13)
    for _ in range(200):
        n = int(rng.integers(1, 9000))
        x = rng.normal(size=(n, 3)) * rng.choice([1.0, 1e3, 1e8]) + rng.normal(size=3) * 1e4
        planes = np.ascontiguousarray(x.T)
        assert np.array_equal(np.cumsum(planes, axis=1)[:, -1] / n, x.mean(0))


def test_masked_rows_is_the_boolean_gather():
    rng = np.random.default_rng(17)
    for trial, h, w, mask in _random_masks(rng, 100):
        big = (rng.random((h + 2, w + 3, 3)) * 255).astype((np.float32, np.uint8)[trial % 2])
        for img in (big[:h, :w], np.ascontiguousarray(big[1:1 + h, 2:2 + w])):
            got = fitting.masked_rows(img, mask)
            assert got.dtype == img.dtype and np.array_equal(got, img[mask]), trial
