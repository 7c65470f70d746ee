"""The eyeball layer behind the eye openings (SPEC §3.2): gaze, pupils, thrust. No Qt.

Per eye, once per face (:class:`EyePlan`), from the neutral photo and the detected iris circle:

* the **white plate**: the photo inside the eye opening with the iris disc filled from the white
  beside it (rows) and, near the lids, from the lids' shadow (inpainting), and continued beyond
  the opening, so that shifted or stretched samples never pick up iris remnants or lid skin;
* the **iris sprite**: the photo's iris disc, its parts hidden by the lids completed (vertical
  mirror when visible there, else the mean colour at the same radius).

Per frame (:meth:`EyePlan.render`), in the neutral eye's coordinates (the eyeball follows the
eye corners, the similarity ``warp`` uses for the opening):

* horizontal gaze Δx (the iris centre 3.5/3.6 as moved by FAPs 23/24 and the head): the white
  right of the split line moves right rigidly, the triangle (left corner, a', b') is filled
  affinely from (left corner, a, b), a/b the points 1/5 along the lids from the left corner
  (mirrored with c/d for gaze left). When the photo's iris reaches into that corner triangle (the
  eye does not look straight ahead), the vertical tangent at the iris edge replaces the a-b line.
  Δx is clamped so that the iris centre does not cross the line c-d (a-b for gaze left; see
  :meth:`EyePlan.gaze_shift` for why not the whole iris as SPEC §3.2 says);
* vertical gaze (FAPs 25/26) moves the iris only (no stretch), the lids clip it;
* the iris is drawn round at its new centre with radius ``r'`` (thrust, FAPs 27/28) and the
  pupil scaled radially to ``p'`` (FAPs 29/30): the iris annulus [p0, r0] maps to [p', r'];
  a dilated pupil also gets a dark disc of the photo's pupil colour (brown irises show
  little of their own pupil), catch-lights spared.

Returns colours only; the caller composites them behind the deformed lids with anti-aliasing.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: FAP indices (0-based) per eye: yaw, pitch, thrust, dilate; eye_l = FDP 3.5, eye_r = 3.6
EYE_FAPS = {"eye_l": (22, 24, 26, 28), "eye_r": (23, 25, 27, 29)}
EXTRA_INDEX = {"eye_l": 0, "eye_r": 1}  # position among deform's extra points (3.5, 3.6)


def _lid_point(lid: np.ndarray, f: float) -> np.ndarray:
    """Point on a lid polyline (frame coords, corner to corner) at fraction f of the x span."""
    u = lid[0, 0] + f * (lid[-1, 0] - lid[0, 0])
    order = np.argsort(lid[:, 0])
    return np.array([u, np.interp(u, lid[order, 0], lid[order, 1])])


def _line_u(p: np.ndarray, q: np.ndarray, w: np.ndarray | float) -> np.ndarray | float:
    """u of the line through p, q (frame coords) at height w."""
    dw = q[1] - p[1]
    if abs(dw) < 1e-6:
        return p[0] + 0.0 * np.asarray(w)
    return p[0] + (np.asarray(w) - p[1]) * (q[0] - p[0]) / dw


def _iris_edges(patch: np.ndarray, opening: np.ndarray, cx: float, cy: float, r: float,
                ex: np.ndarray, ey: np.ndarray) -> tuple[float, float, float]:
    """Refine the iris from its left and right edges (the paper's Canny edge points).

    The luminance is averaged over the rows near the centre (pixels inside the opening only)
    along the eye's horizontal; the left edge is the strongest bright-to-dark step left of the
    centre, the right edge the strongest dark-to-bright step right of it. Kept only when both
    are clear and give a radius within 0.75-1.7 of the detector's; else the circle is unchanged.
    """
    g = cv2.cvtColor(patch, cv2.COLOR_RGB2GRAY).astype(np.float32)
    m = opening.astype(np.float32)
    us = np.arange(-2.0 * r, 2.0 * r + 1e-6, 0.25)
    ws = np.linspace(-0.4 * r, 0.4 * r, 7)
    U, W = np.meshgrid(us, ws)
    mx = (cx + U * ex[0] + W * ey[0]).astype(np.float32)
    my = (cy + U * ex[1] + W * ey[1]).astype(np.float32)
    lum = cv2.remap(g, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    vis = cv2.remap(m, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT) > 0.99
    cnt = vis.sum(0)
    prof = (lum * vis).sum(0) / np.maximum(cnt, 1)
    ok = cnt >= 2
    if ok.sum() < 8:
        return cx, cy, r
    prof = np.interp(us, us[ok], prof[ok])
    prof = np.convolve(np.pad(prof, 2, mode="edge"), np.ones(5) / 5.0, mode="valid")
    grad = np.gradient(prof, us)
    left = (us > -1.8 * r) & (us < -0.5 * r) & ok
    right = (us < 1.8 * r) & (us > 0.5 * r) & ok
    if not left.any() or not right.any():
        return cx, cy, r
    il = np.flatnonzero(left)[np.argmin(grad[left])]
    ir = np.flatnonzero(right)[np.argmax(grad[right])]
    spread = float(np.ptp(prof[ok])) + 1e-6
    strong = min(-grad[il], grad[ir]) * r / spread > 0.35
    re = 0.5 * (us[ir] - us[il])
    if not strong or not 0.75 * r <= re <= 1.7 * r:
        return cx, cy, r
    uc = 0.5 * (us[ir] + us[il])
    return cx + uc * ex[0], cy + uc * ex[1], float(re)


def _white_plate(patch: np.ndarray, opening: np.ndarray, rho: np.ndarray, r_fill: float,
                 radius: float) -> np.ndarray:
    """The white of the eye without the iris, continued beyond the opening (float32).

    Inside the disc ``rho < r_fill``: away from the lids, each row is interpolated between the
    white left and right of the disc; towards the lids this blends into an inpainting (OpenCV
    Telea) of the disc from its surroundings, which carries the lids' shadow; the result is
    smoothed so that no lash texture shows, and feathered into the photo over the disc's last
    pixel. Outside the opening each column repeats its nearest value inside (shifted samples
    near the lids then stay eye-coloured).
    """
    outside_iris = rho >= r_fill
    disc = opening & ~outside_iris
    out = patch.astype(np.float32)
    if disc.any():
        tel = cv2.inpaint(patch, disc.astype(np.uint8), max(2.0, 0.5 * radius),
                          cv2.INPAINT_TELEA).astype(np.float32)
        d_lid = cv2.distanceTransform(opening.astype(np.uint8), cv2.DIST_L2, 3)
        known = opening & outside_iris & (d_lid > 1.0)  # the white, clear of the lash line
        rows = tel.copy()
        wrow = np.zeros(opening.shape, np.float32)
        cols = np.arange(opening.shape[1])
        for i in np.flatnonzero(disc.any(1)):
            k = np.flatnonzero(known[i])
            f = np.flatnonzero(disc[i])
            if len(k) == 0 or k.min() > f.min() or k.max() < f.max():
                continue  # white on both sides of the disc only
            for ch in range(3):
                rows[i, f, ch] = np.interp(cols[f], k, out[i, k, ch])
            wrow[i, f] = 1.0
        wv = (np.clip((d_lid - 0.5) / 2.0, 0.0, 1.0) * wrow)[..., None]
        fill = wv * rows + (1.0 - wv) * tel
        fill = cv2.GaussianBlur(fill, (0, 0), max(0.6, 0.25 * radius))
        w = (np.clip(r_fill - rho, 0.0, 1.0) * opening)[..., None].astype(np.float32)
        out = w * fill + (1.0 - w) * out
    ph, pw = opening.shape
    for j in range(pw):
        r_in = np.flatnonzero(opening[:, j])
        if len(r_in) == 0:
            continue
        out[: r_in[0], j] = out[r_in[0], j]
        out[r_in[-1] + 1:, j] = out[r_in[-1], j]
    empty = ~opening.any(0)
    if empty.any() and (~empty).any():
        full = np.flatnonzero(~empty)
        for j in np.flatnonzero(empty):
            out[:, j] = out[:, full[np.argmin(np.abs(full - j))]]
    return out

@dataclass(eq=False)
class EyePlan:
    """Precomputed eyeball of one eye (see module docstring)."""

    name: str
    hole: np.ndarray  # vertex loop of the opening
    detected: np.ndarray  # (2,) iris centre of the landmarks (= neutral FDP 3.5/3.6)
    r_det: float  # iris radius of the landmarks (the one deform.eye_state scales)
    centre: np.ndarray  # (2,) iris centre refined from its edges, image px
    r0: float  # iris radius refined from its edges
    p0: float  # neutral pupil radius (deform.eye_state with zero FAPs)
    ex: np.ndarray
    ey: np.ndarray
    off: np.ndarray  # (2,) image position of plate[0, 0]
    plate: np.ndarray  # (h, w, 3) float32 white of the eye
    photo: np.ndarray  # (h, w, 3) float32 the photo over the same patch
    iris: np.ndarray  # (h, w, 3) float32 completed iris (valid inside r_fill + 1)
    split_r: tuple[np.ndarray, np.ndarray]  # split line for gaze right (frame, iris-centred)
    split_l: tuple[np.ndarray, np.ndarray]
    corner_l: np.ndarray  # image-left eye corner (frame, iris-centred)
    corner_r: np.ndarray
    lim_r: float  # u of the clamp line c-d at the iris height
    lim_l: float
    pupil: np.ndarray  # (3,) colour of the photo's pupil
    iris_lum: float  # median luminance of the visible iris

    @classmethod
    def build(cls, image: np.ndarray, vertices: np.ndarray, hole: np.ndarray, name: str,
              iris: tuple[float, float, float], frame_rot: np.ndarray) -> EyePlan:
        cx, cy, r = (float(x) for x in iris)
        r = max(r, 1.0)
        detected, r_det = np.array([cx, cy]), r
        ex, ey = frame_rot[:, 0].astype(np.float64), frame_rot[:, 1].astype(np.float64)
        poly = vertices[hole].astype(np.float64)
        h, w = image.shape[:2]
        m = int(np.ceil(2.0 * r)) + 4
        x0 = int(max(0, np.floor(poly[:, 0].min()) - m))
        y0 = int(max(0, np.floor(poly[:, 1].min()) - m))
        x1 = int(min(w, np.ceil(poly[:, 0].max()) + m + 1))
        y1 = int(min(h, np.ceil(poly[:, 1].max()) + m + 1))
        patch = np.ascontiguousarray(image[y0:y1, x0:x1])
        ph, pw = patch.shape[:2]
        opening = np.zeros((ph, pw), np.uint8)
        cv2.fillPoly(opening, [np.round((poly - (x0, y0)) * 16).astype(np.int32)], 1,
                     cv2.LINE_8, 4)
        cx, cy, r = _iris_edges(patch, opening, cx - x0, cy - y0, r, ex, ey)
        cx, cy = cx + x0, cy + y0
        yy, xx = np.mgrid[0:ph, 0:pw].astype(np.float64)
        rho = np.hypot(xx + x0 - cx, yy + y0 - cy)
        r_fill = r + max(1.5, 0.3 * r)  # the limbus and its blur go too (no ring remnant)
        plate = _white_plate(patch, opening > 0, rho, r_fill, r)
        # iris sprite: visible = inside the opening, one pixel clear of the lid edge
        vis = cv2.erode(opening, np.ones((3, 3), np.uint8)) > 0
        src = patch.astype(np.float32)
        out = src.copy()
        need = (rho <= r_fill + 1.5) & (opening == 0)  # the photo's own pixels stay
        if need.any():
            my = np.clip(np.rint(2 * (cy - y0) - yy), 0, ph - 1).astype(np.int64)
            mx = xx.astype(np.int64)
            mirror_ok = need & vis[my, mx]
            out[mirror_ok] = src[my[mirror_ok], mx[mirror_ok]]
            rest = need & ~mirror_ok
            if rest.any():
                bins = np.minimum((rho * 2).astype(np.int64), int(2 * (r_fill + 2)))
                nb = int(bins.max()) + 1
                sel = vis & (rho <= r_fill + 1.5)
                cnt = np.bincount(bins[sel], minlength=nb)
                mean = np.zeros((nb, 3), np.float32)
                if cnt.any():
                    for ch in range(3):
                        s = np.bincount(bins[sel], src[..., ch][sel], minlength=nb)
                        okb = cnt > 0
                        mean[:, ch] = np.interp(np.arange(nb), np.flatnonzero(okb),
                                                s[okb] / cnt[okb])
                else:
                    mean[:] = np.percentile(src.reshape(-1, 3), 10, axis=0)
                out[rest] = mean[bins[rest]]
        # corner / 1/5 points in frame coordinates centred on the iris
        names_u = [0, 1, 2, 3, 4, 5, 6]
        loop = poly
        up = loop[names_u]  # c0, u1..u5, c1
        lo = loop[[0, 11, 10, 9, 8, 7, 6]]  # c0, d1..d5, c1
        c = np.array([cx, cy])

        def fr(p: np.ndarray) -> np.ndarray:
            d = np.atleast_2d(p) - c
            return np.stack([d @ ex, d @ ey], -1)

        upf, lof = fr(up), fr(lo)
        a, b = _lid_point(upf, 0.2), _lid_point(lof, 0.2)
        cc, dd = _lid_point(upf, 0.8), _lid_point(lof, 0.8)
        # the paper's 1/5 points, or the iris edge when the iris reaches into a corner triangle
        split_r = (a, b) if _line_u(a, b, 0.0) <= -r else (
            np.array([-r, a[1]]), np.array([-r, b[1]]))
        split_l = (cc, dd) if _line_u(cc, dd, 0.0) >= r else (
            np.array([r, cc[1]]), np.array([r, dd[1]]))
        p0 = r / 3.0
        core = vis & (rho <= 0.6 * r)
        ring = vis & (rho <= r)
        lum = src @ np.array([0.299, 0.587, 0.114], np.float32)
        if core.sum() >= 3 and ring.sum() >= 3:
            k = core & (lum <= np.percentile(lum[core], 25))
            pupil = src[k].mean(0)
            iris_l = float(np.median(lum[ring]))
        else:
            pupil, iris_l = np.full(3, 20.0, np.float32), 60.0
        return cls(pupil=pupil.astype(np.float32), iris_lum=iris_l, name=name,
                   hole=np.asarray(hole), detected=detected, r_det=r_det, centre=c,
                   r0=r, p0=p0, ex=ex, ey=ey, off=np.array([x0, y0], np.float64), plate=plate,
                   photo=patch.astype(np.float32),
                   iris=out, split_r=split_r, split_l=split_l, corner_l=upf[0],
                   corner_r=upf[-1], lim_r=float(_line_u(cc, dd, 0.0)),
                   lim_l=float(_line_u(a, b, 0.0)))

    # ------------------------------------------------------------------ per frame
    def gaze_shift(self, iris_dst: np.ndarray, sim: np.ndarray) -> np.ndarray:
        """(Δu, Δw) of the iris in the neutral eye's frame, Δu clamped at c-d / a-b.

        The clamp holds the iris *centre* on the near side of the line c-d (a-b for gaze
        left), so the iris may enter the corner triangle by up to its radius, where the lids
        clip it. SPEC §3.2 keeps the whole iris out; on real photos (the irises sit nasally,
        converging on the camera) that leaves 0.4-2.5 px of travel, different for the two
        eyes, and a common gaze then makes the eyes diverge.
        """
        inv = cv2.invertAffineTransform(np.asarray(sim, np.float64))
        n = inv[:, :2] @ np.asarray(iris_dst, np.float64) + inv[:, 2]
        d = n - self.detected
        du, dw = float(d @ self.ex), float(d @ self.ey)
        if du > 0:
            du = min(du, max(0.0, self.lim_r))
        elif du < 0:
            du = max(du, min(0.0, self.lim_l))
        return np.array([du, dw])

    def render(self, box: tuple[int, int, int, int], sim: np.ndarray, shift: np.ndarray,
               r_new: float, p_new: float) -> np.ndarray:
        """Colours (h, w, 3) float32 of the eyeball over ``box`` of the output image.

        ``r_new``, ``p_new``: iris and pupil radii from :func:`deform.eye_state` (they are
        rescaled to the edge-refined iris radius).
        """
        k = self.r0 / self.r_det
        r_new, p_new = r_new * k, p_new * k
        x0, y0, x1, y1 = box
        inv = cv2.invertAffineTransform(np.asarray(sim, np.float64))
        xs = np.arange(x0, x1, dtype=np.float64)[None, :]
        ys = np.arange(y0, y1, dtype=np.float64)[:, None]
        nx = inv[0, 0] * xs + inv[0, 1] * ys + inv[0, 2] - self.centre[0]
        ny = inv[1, 0] * xs + inv[1, 1] * ys + inv[1, 2] - self.centre[1]
        ex, ey = self.ex, self.ey
        U = nx * ex[0] + ny * ex[1]
        W = nx * ey[0] + ny * ey[1]
        du, dw = float(shift[0]), float(shift[1])
        # the white: stretch / translate horizontally
        Us, Ws = U, W
        if abs(du) > 1e-6:
            p, q = self.split_r if du > 0 else self.split_l
            corner = self.corner_l if du > 0 else self.corner_r
            bound = _line_u(p, q, W) + du
            moved = (U >= bound) if du > 0 else (U <= bound)
            dst = np.float32([corner, p + (du, 0.0), q + (du, 0.0)])
            src = np.float32([corner, p, q])
            A = cv2.getAffineTransform(dst, src).astype(np.float64)
            Ua = A[0, 0] * U + A[0, 1] * W + A[0, 2]
            Wa = A[1, 0] * U + A[1, 1] * W + A[1, 2]
            Us = np.where(moved, U - du, Ua)
            Ws = np.where(moved, W, Wa)
        ox = self.centre[0] - self.off[0]
        oy = self.centre[1] - self.off[1]
        mx = (ox + Us * ex[0] + Ws * ey[0]).astype(np.float32)
        my = (oy + Us * ex[1] + Ws * ey[1]).astype(np.float32)
        # at rest the white is the photo itself (the composite is then exactly the photo); it
        # turns into the clean plate within the first pixel of motion or radius change
        t = max(abs(du), abs(dw), 2.0 * abs(r_new - self.r0))
        t = t * t * (3.0 - 2.0 * t) if t < 1.0 else 1.0
        plate = self.plate if t >= 1.0 else self.photo + t * (self.plate - self.photo)
        white = cv2.remap(plate, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        # the iris: rigid, round, radially rescaled for thrust and pupil size
        Di = U - du
        Dw = W - dw
        rho = np.sqrt(Di * Di + Dw * Dw)
        a = np.clip(r_new + 1.0 - rho, 0.0, 1.0)  # the limbus blur is part of the iris
        if not a.any():
            return white
        rn = rho / max(r_new, 1e-6)
        pn, pn0 = p_new / max(r_new, 1e-6), self.p0 / self.r0
        pn = min(max(pn, 0.02), 0.95)
        rs = np.where(rn < pn, rn * pn0 / pn,
                      pn0 + (rn - pn) * (1.0 - pn0) / (1.0 - pn)) * self.r0
        k = rs / np.maximum(rho, 1e-6)
        ix = (ox + k * (Di * ex[0] + Dw * ey[0])).astype(np.float32)
        iy = (oy + k * (Di * ex[1] + Dw * ey[1])).astype(np.float32)
        iris = cv2.remap(self.iris, ix, iy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        p_rest = self.p0 * r_new / self.r0
        if p_new > p_rest:
            # a dilated pupil: the photo's pupil, radially stretched, may be faint (brown
            # irises); a dark disc of the pupil's colour fades in, sparing the catch-lights
            w = min((p_new - p_rest) / max(1.0, 0.3 * p_rest), 1.0)
            ap = np.clip(p_new + 0.5 - rho, 0.0, 1.0).astype(np.float32) * w
            lum = iris @ np.array([0.299, 0.587, 0.114], np.float32)
            ap *= 1.0 - np.clip((lum - 1.3 * self.iris_lum) / (0.3 * self.iris_lum + 1.0),
                                0.0, 1.0)
            ap = ap[..., None]
            iris = iris * (1.0 - ap) + self.pupil * ap
        a = a.astype(np.float32)[..., None]
        return iris * a + white * (1.0 - a)


def photo_through(img: np.ndarray, sim: np.ndarray, box: tuple[int, int, int, int]
                  ) -> np.ndarray:
    """The photo seen through the opening, moved by ``sim`` (source -> destination)."""
    x0, y0, x1, y1 = box
    inv = cv2.invertAffineTransform(np.asarray(sim, np.float64))
    xs = np.arange(x0, x1, dtype=np.float32)[None, :]
    ys = np.arange(y0, y1, dtype=np.float32)[:, None]
    mx = (inv[0, 0] * xs + inv[0, 1] * ys + inv[0, 2]).astype(np.float32)
    my = (inv[1, 0] * xs + inv[1, 1] * ys + inv[1, 2]).astype(np.float32)
    return cv2.remap(img, mx, my, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE).astype(np.float32)
