"""Round trips through the FACS and ARKit tables, measured in FAPU (issue 19, item 5).

``python scripts/facs_roundtrip.py [--jaffe DIR] [--no-jaffe]``

1. FAP -> ARKit -> FAP and FAP -> AU -> FAP on the six shipped emotion presets: RMS and
   largest error over the preset's non-zero FAPs (FAPU), and the FAP that loses most.
2. The same on real measured FAP vectors: every JAFFE expression photo's feature-point motion
   against the woman's neutral, along 35 FAP axes (``editor.synthesis.jaffe_stats.measure``;
   lower-lip motion taken relative to the chin, as the renderer carries the lip with the jaw),
   when JAFFE is available (research-only data: statistics printed, nothing stored).
3. AU -> FAP -> AU on the FACS prototypes of SPEC §7.4 at intensity C (0.6): largest AU error.
   There are no real ``.fap`` recordings in the repository or the shared folder to add.

Prints markdown tables (what README's round-trip section quotes).
"""

from __future__ import annotations

import argparse

import numpy as np

from editor.engine.faps import FAPS
from editor.formats.arkit import arkit_to_faps, faps_to_arkit
from editor.formats.facs import au_table, aus_to_faps, column_weights, faps_to_aus
from editor.formats.presets import apply_preset, get_preset

EMOTIONS = ("joy", "sadness", "anger", "fear", "disgust", "surprise")
#: SPEC §7.4 (EMFACS prototypes)
PROTOTYPES = {"joy": (6, 12), "sadness": (1, 4, 15), "surprise": (1, 2, 5, 26),
              "fear": (1, 2, 4, 5, 7, 20, 26), "anger": (4, 5, 7, 23), "disgust": (9, 15, 16)}


#: lower-lip FAPs (5, 10, 11, 52, 57, 58), 0-based
LOWER_LIP = [4, 9, 10, 51, 56, 57]


def via_arkit(f: np.ndarray) -> np.ndarray:
    w, r = faps_to_arkit(f)
    return arkit_to_faps(w, r)


def via_au(f: np.ndarray) -> np.ndarray:
    return aus_to_faps(faps_to_aus(f))


def errors(f: np.ndarray, back: np.ndarray) -> tuple[float, float, str]:
    """RMS and max |error| over the non-zero FAPs of f, and the name of the worst FAP."""
    nz = np.flatnonzero(f)
    e = (back - f)[..., nz]
    worst = int(nz[int(np.argmax(np.abs(e).max(axis=0) if e.ndim > 1 else np.abs(e)))])
    return float(np.sqrt(np.mean(e ** 2))), float(np.abs(e).max()), FAPS[worst + 1].name


def preset_table() -> None:
    print("| preset | FAPs | ARKit RMS | ARKit max (FAP) | AU RMS | AU max (FAP) |")
    print("|---|---|---|---|---|---|")
    for name in EMOTIONS:
        f = apply_preset(get_preset(name), 1.0).astype(np.float64)
        ra, ma, wa = errors(f, via_arkit(f)[0])
        ru, mu, wu = errors(f, via_au(f)[0])
        print(f"| {name} | {np.count_nonzero(f)} | {ra:.1f} | {ma:.0f} ({wa}) | {ru:.1f} | "
              f"{mu:.0f} ({wu}) |")


def jaffe_table(root: str | None) -> None:
    from editor.synthesis.jaffe_stats import measure

    try:
        m = measure(root)
    except FileNotFoundError as e:
        print(f"(JAFFE not available: {e})")
        return
    idx = np.array(m.faps) - 1
    print("\n| JAFFE emotion | photos | ARKit RMS (median) | AU RMS (median) | "
          "RMS of the motion itself (median) |")
    print("|---|---|---|---|---|")
    for emo in EMOTIONS:
        v = m.values(emo)
        f = np.zeros((len(v), 68))
        f[:, idx] = v
        # measured lower-lip motion includes the jaw's: the renderer carries the lower lip
        # with the chin (FAP 3), so the lip FAPs are the motion relative to the chin
        f[:, LOWER_LIP] += f[:, [2]]
        ea = np.sqrt(np.mean((via_arkit(f)[:, idx] - f[:, idx]) ** 2, axis=1))
        eu = np.sqrt(np.mean((via_au(f)[:, idx] - f[:, idx]) ** 2, axis=1))
        own = np.sqrt(np.mean(f[:, idx] ** 2, axis=1))
        print(f"| {emo} | {len(v)} | {np.median(ea):.0f} | {np.median(eu):.0f} | "
              f"{np.median(own):.0f} |")


def prototype_table() -> None:
    table = au_table()
    print("\n| prototype (AUs at C = 0.6) | largest AU error | AUs the fit adds (> 0.05) |")
    print("|---|---|---|")
    for emo, aus in PROTOTYPES.items():
        w = column_weights({str(a): 0.6 for a in aus})
        back = table.to_bilateral(faps_to_aus(aus_to_faps(w)))[0]
        want = table.to_bilateral(w)[0]
        err = np.abs(back - want)
        extra = [f"AU{a.number} {back[j]:.2f}" for j, a in enumerate(table.aus)
                 if a.number not in aus and back[j] > 0.05]
        print(f"| {emo}: {'+'.join(str(a) for a in aus)} | {err.max():.2f} "
              f"(AU{table.aus[int(np.argmax(err))].number}) | {', '.join(extra) or '-'} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jaffe", help="JAFFE folder (default: $FAP_STUDIO_JAFFE or ../shared)")
    ap.add_argument("--no-jaffe", action="store_true", help="presets and prototypes only")
    a = ap.parse_args()
    preset_table()
    if not a.no_jaffe:
        jaffe_table(a.jaffe)
    prototype_table()


if __name__ == "__main__":
    main()
