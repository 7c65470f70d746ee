"""Draw the mouth-interior textures of SPEC §3.1 (upper teeth, lower teeth, tongue).

``python scripts/draw_mouth_textures.py [OUT_DIR]`` (default ``editor/data/mouth``) writes three
RGBA PNGs. Everything is procedural (numpy + OpenCV, fixed random seed): no photographs, no
downloads. Drawn at 4x and reduced with area averaging, so the edges are anti-aliased.

Geometry, in millimetres at 10 px/mm (the renderer only keeps the aspect ratio: the teeth are
scaled to half the mouth-nose distance, the tongue to the mouth width, SPEC eq. 6):

* teeth: the arch is a circle seen from the front; each tooth occupies the arc given by its
  mesiodistal width (typical adult values) and projects to ``R sin(phi)``, so canines and
  premolars are foreshortened and shaded darker (they face sideways, deeper in the mouth).
  Each crown is a rounded slab with a scalloped gum margin, an ivory body, a greyer
  translucent incisal edge and dark contact lines; the canines are pointed. The gum is a pink
  band on the root side (top of the upper teeth, bottom of the lower teeth). Transparent past
  the incisal edges and past the last tooth.
* tongue: seen from the front as it lies behind the lower teeth: a broad rounded dorsum whose
  far part (top of the image) is in shadow, darker sides, a faint median groove, papillae as
  a fixed-seed speckle, a soft moist highlight, and a soft silhouette (its far edge and
  sides curve away into the dark).
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from editor.resources import MOUTH_DIR, source_path  # noqa: E402

PX_PER_MM = 10
SS = 4  # supersampling


# (mesiodistal width mm, crown length mm, pointed tip) from the midline backwards
UPPER = [(8.5, 10.5, False), (6.6, 9.0, False), (7.6, 10.0, True), (7.0, 8.2, False),
         (6.6, 7.6, False), (10.0, 7.0, False)]
LOWER = [(5.2, 9.6, False), (5.8, 9.8, False), (6.8, 10.0, True), (7.0, 8.4, False),
         (7.0, 7.8, False), (11.0, 7.4, False)]


def _smooth(t: np.ndarray) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t)


def draw_teeth(widths: list[tuple[float, float, bool]], radius: float, size_mm: tuple[float, float],
               gum_mm: float, upper: bool, shade: float) -> np.ndarray:
    """RGBA float image (h, w, 4) in [0, 1], gum at the top (flipped for the lower teeth)."""
    W, H = size_mm
    s = PX_PER_MM * SS
    w, h = int(round(W * s)), int(round(H * s))
    xs = (np.arange(w) + 0.5) / s - W / 2  # mm, 0 = midline
    ys = (np.arange(h) + 0.5) / s  # mm from the gum side
    X, Y = np.meshgrid(xs, ys)
    rgb = np.zeros((h, w, 3))
    alpha = np.zeros((h, w))
    ivory = np.array([0.93, 0.90, 0.83])
    neck = np.array([0.86, 0.80, 0.66])
    edge = np.array([0.76, 0.78, 0.82])
    gum = np.array([0.78, 0.42, 0.44])
    # arch: tooth k spans arc [s0, s1] -> angles -> projected x = R sin(phi)
    s0 = 0.0
    spans = []
    for wd, ln, pointed in widths:
        phi0, phi1 = s0 / radius, (s0 + wd) / radius
        s0 += wd
        if phi0 >= np.pi / 2:
            break
        spans.append((radius * np.sin(phi0), radius * np.sin(min(phi1, np.pi / 2)),
                      0.5 * (phi0 + min(phi1, np.pi / 2)), ln, pointed))
    rng = np.random.default_rng(11 if upper else 12)
    for side in (-1.0, 1.0):
        for x0, x1, phi, ln0, pointed in spans:
            # no two upper teeth alike: each a little lighter or darker and longer or shorter
            # (the lower ones, mostly hidden and in shadow, stay even)
            vary = float(upper)
            tone = 1.0 + vary * float(rng.uniform(-0.035, 0.035))
            ln = ln0 + vary * float(rng.uniform(-0.25, 0.25))
            a, b = (x0, x1) if side > 0 else (-x1, -x0)
            tw = b - a
            t = (X - a) / max(tw, 1e-6)  # 0..1 across the tooth
            inside_x = (t >= 0) & (t <= 1)
            persp = 0.80 + 0.20 * np.cos(phi)  # posterior crowns look shorter
            crown = ln * persp
            # a shorter crown's gingival margin sits lower (laterals' zenith ~1 mm below the
            # centrals'): its incisal edge ends only ~40 % of the length difference higher,
            # not all of it (1.8 mm left only a 1-px sliver of laterals in a modest opening)
            drop = 0.6 * (widths[0][1] - ln) * persp
            # gum margin: scalloped, highest (towards the root) at the tooth centre
            margin = gum_mm + drop + 0.9 * (1 - np.sin(np.pi * np.clip(t, 0, 1))) - 0.3
            # smile arc: posterior incisal edges rise towards the gum
            tip = gum_mm + drop + crown - 1.6 * (1 - np.cos(phi))
            if pointed:
                tip = tip + 0.9 * (1 - np.abs(2 * t - 1)) - 0.5
            # rounded incisal corners: nearly square towards the midline (mesial), rounder
            # distally; large radii on both sides cut V notches between the teeth that read
            # as dark dots once the row is a dozen pixels tall
            dx = np.minimum(t, 1 - t) * tw
            tm = np.clip(t if side > 0 else 1 - t, 0, 1)  # 0 at the mesial side
            round_off = np.zeros_like(t)
            for d, r in ((tm * tw, 0.10 * tw), ((1 - tm) * tw, 0.22 * tw)):
                round_off += np.where(d < r, r - np.sqrt(np.maximum(r ** 2 - (r - d) ** 2,
                                                                    0.0)), 0.0)
            tip_here = tip - round_off
            body = inside_x & (Y >= margin) & (Y <= tip_here)
            if not body.any():
                continue
            v = np.clip((Y - margin) / np.maximum(tip_here - margin, 1e-6), 0, 1)
            col = (neck[None, None] * (1 - _smooth(v / 0.35))[..., None]
                   + ivory[None, None] * _smooth(v / 0.35)[..., None])
            # the translucent incisal edge: greyer and a little blue, over its last fifth
            near_edge = _smooth((v - 0.80) / 0.20)[..., None]
            col = col * (1 - 0.45 * near_edge) + edge[None, None] * 0.45 * near_edge
            roundness = 0.72 + 0.28 * np.sin(np.pi * np.clip(t, 0, 1)) ** 0.6
            # the labial surface: a faint groove between the lobes of the incisors (at a
            # third and two thirds of the width, fading towards the edge) and the wet
            # enamel's soft highlight a little mesial of the crown's middle, strongest in its
            # middle third (a crown of even light reads as a plastic block at a large size);
            # the lower teeth, in the upper ones' shadow, have neither
            lobes = 1.0 - (0.035 if upper and ln > 8.5 else 0.0) * (
                np.exp(-((t - 1 / 3) / 0.05) ** 2) + np.exp(-((t - 2 / 3) / 0.05) ** 2)) * (
                1.0 - _smooth((v - 0.55) / 0.35))
            tc = 0.42 if side > 0 else 0.58  # (mesial of the middle)
            gloss = 1.0 + (0.09 if upper else 0.0) * (np.exp(-((t - tc) / 0.09) ** 2)
                                                      * np.exp(-((v - 0.45) / 0.25) ** 2))
            light = (shade * tone * (0.45 + 0.55 * np.cos(phi) ** 1.3) * roundness
                     * (0.78 + 0.22 * v) * lobes * gloss)
            col = col * light[..., None]
            # contact lines between neighbours: the interproximal shadow, ~0.35 mm on each
            # side and darkest towards the incisal edge and the gum (the embrasures), so that
            # at ~1 px/mm (a 256-px face) each gap still dips by about a third
            contact = _smooth(dx / 0.35)
            emb = 0.55 + 0.45 * np.maximum(_smooth((v - 0.6) / 0.4), _smooth((0.25 - v) / 0.25))
            col = col * (1.0 - 0.5 * emb * (1.0 - contact))[..., None]
            rgb[body] = col[body]
            alpha[body] = 1.0
    # gum band (behind the margins) across the visible arch
    half = spans[-1][1]
    gum_zone = (Y < gum_mm + 1.2) & (np.abs(X) <= half) & (alpha == 0)
    g = np.clip(1 - np.abs(X) / max(half, 1e-6), 0, 1)
    gum_col = gum[None, None] * (shade * (0.5 + 0.5 * g) * (0.75 + 0.25 * np.clip(
        Y / gum_mm, 0, 1)))[..., None]
    rgb[gum_zone] = gum_col[gum_zone]
    alpha[gum_zone] = 1.0
    out = np.dstack([rgb, alpha])
    if not upper:
        out = out[::-1]
    return out


def draw_tongue(size_mm: tuple[float, float] = (40.0, 30.0), seed: int = 6) -> np.ndarray:
    W, H = size_mm
    s = PX_PER_MM * SS
    w, h = int(round(W * s)), int(round(H * s))
    xs = (np.arange(w) + 0.5) / s - W / 2
    ys = (np.arange(h) + 0.5) / s
    X, Y = np.meshgrid(xs, ys)
    # silhouette: a rounded dorsum, widest at the bottom (hidden behind the lower lip)
    half_w = 0.5 * W - 0.3
    top = 1.0 + 7.0 * (np.abs(X) / half_w) ** 2.2
    # its far edge and sides curve away into the mouth's shadow: a soft silhouette (a hard
    # one reads as a cut-out shape against the dark cavity)
    inside = _smooth((Y - top) / 2.0) * _smooth((half_w - np.abs(X)) / 1.5)
    u = np.clip(np.abs(X) / half_w, 0, 1)
    depth = np.clip((Y - top) / (0.55 * H), 0, 1)  # 0 at the far edge, 1 towards the tip
    base = np.array([0.80, 0.40, 0.42])
    light = (0.40 + 0.60 * _smooth(depth)) * (1 - 0.4 * u ** 2.5)
    # median groove, fading towards the tip
    groove = np.exp(-(X / 1.2) ** 2) * (1 - depth) ** 1.5
    light *= 1 - 0.12 * groove
    rng = np.random.default_rng(seed)
    speck = rng.normal(0, 1, (h // SS + 1, w // SS + 1)).astype(np.float32)
    speck = cv2.GaussianBlur(speck, (0, 0), 0.8)
    speck = cv2.resize(speck, (w, h), interpolation=cv2.INTER_LINEAR)
    col = base[None, None] * light[..., None] * (1 + 0.06 * speck[..., None])
    # moist highlight on the front of the dorsum
    hl = np.exp(-((X / 7.0) ** 2 + ((Y - 0.55 * H) / 3.0) ** 2))
    col = col * (1 - 0.25 * hl[..., None]) + np.array([0.95, 0.72, 0.72]) * 0.25 * hl[..., None]
    rgb = np.where(inside[..., None] > 0, col, 0.0)
    return np.dstack([rgb, inside])


def _save(path: Path, rgba: np.ndarray) -> None:
    h, w = rgba.shape[:2]
    small = cv2.resize(rgba.astype(np.float32), (w // SS, h // SS), interpolation=cv2.INTER_AREA)
    a = small[..., 3:4]
    # straight (non-premultiplied) colour where partly covered
    rgb = np.where(a > 1e-4, small[..., :3] / np.maximum(a, 1e-4), 0.0)
    out = np.dstack([rgb, a])
    out8 = np.clip(np.rint(out * 255), 0, 255).astype(np.uint8)
    bgra = out8[..., [2, 1, 0, 3]]
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), bgra):
        raise OSError(f"cannot write {path}")
    print(path, f"{w // SS}x{h // SS}")


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else source_path(MOUTH_DIR)
    # premultiplied while drawing/reducing: multiply colour by alpha before the area reduction
    for name, img in (
        ("upper_teeth.png", draw_teeth(UPPER, 22.0, (46.0, 13.0), 2.6, True, 1.0)),
        ("lower_teeth.png", draw_teeth(LOWER, 19.0, (40.0, 12.0), 2.2, False, 0.92)),
        ("tongue.png", draw_tongue()),
    ):
        pm = img.copy()
        pm[..., :3] *= pm[..., 3:4]
        _save(out / name, pm)


if __name__ == "__main__":
    main()
